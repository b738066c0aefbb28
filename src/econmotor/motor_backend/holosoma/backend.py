"""HolosomaBackend: Amazon FAR's Holosoma (G1/T1 humanoids) trained under an economic objective.

Holosoma pins numpy<2, so it lives in its own interpreter (``make holosoma`` builds
``.venv-holosoma`` from ``requirements-holosoma.txt``, econmotor included). This module
only plans and launches jobs there (:mod:`.holosoma.jobs`); it imports neither Holosoma
nor torch, so it works in the main environment without Holosoma installed.

Task map (:data:`HOLOSOMA_TASK_PRESETS`; a task's ``backends.holosoma`` catalog entry
overrides it): ``humanoid_locomotion_g1`` -> ``g1_29dof`` / ``g1_29dof_fast_sac``,
``humanoid_locomotion_t1`` -> ``t1_29dof`` / ``t1_29dof_fast_sac``, ``humanoid_wbt_g1``
-> ``g1_29dof_wbt`` / ``g1_29dof_wbt_fast_sac``.

- **train_policy**: the objective compiles to overlay scales; each overlay key with a
  simulator term becomes a Holosoma reward term weighted ``overlay_gain * scale``
  (:mod:`.reward_terms`); datapacks become randomization / curriculum / terrain /
  motion-file overrides (:mod:`.holosoma.datapack_mapping`); ``max_steps`` counts
  environment steps and is adapted to the simulator (:mod:`.holosoma.plan`, every change
  announced as a ``holosoma: ...`` progress label and kept in ``config["messages"]``).
  Then ``eval_episodes`` episodes are evaluated.
- **evaluate_policy**: Holosoma's ``eval_agent`` with its recording callback (extended);
  raw metrics per episode from the recording (:mod:`.holosoma.recording_metrics`), econ
  metrics from :func:`summarize_episodes`.
- **deploy_policy_handle**: an onnxruntime session over Holosoma's exported ONNX,
  carrying Holosoma's metadata (``dof_names``, ``kp``, ``kd``, ``action_scale``, ...) and
  ours (``econmotor_*``: task, objective, overlay weights, task economics).

``policy_id`` is the run directory holding ``policy.json`` (or an ``.onnx`` file for deploy).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.errors import BackendError, ConfigError
from econmotor.motor_backend.base import (
    MotorEvalResult,
    MotorTrainingResult,
    ProgressFn,
    StepAlias,
    no_progress,
    summarize_episodes,
)
from econmotor.motor_backend.datapacks import DatapackConfig, DatapackProvider
from econmotor.motor_backend.holosoma.datapack_mapping import map_datapacks
from econmotor.motor_backend.holosoma.econ_formulas import OVERLAY_TERM_KEYS
from econmotor.motor_backend.holosoma.jobs import run_job
from econmotor.motor_backend.holosoma.plan import (
    DEFAULT_CPU_MAX_ENV_STEPS,
    HOLOSOMA_TASK_PRESETS,
    Capabilities,
    choose_simulator,
    plan_training,
    task_settings,
)
from econmotor.motor_backend.holosoma.recording_metrics import episodes_from_recording
from econmotor.objectives.economic_objective import EconomicObjectiveSpec, compile_economic_overlay
from econmotor.tasks import get_task

__all__ = ["HOLOSOMA_TASK_PRESETS", "HolosomaBackend", "HolosomaPolicyHandle", "find_holosoma_python"]

VENV_ENV = "ECONMOTOR_HOLOSOMA_VENV"
SIMULATOR_ENV = "ECONMOTOR_HOLOSOMA_SIMULATOR"
ALGO_ENV = "ECONMOTOR_HOLOSOMA_ALGO"
MANIFEST = "policy.json"
_REPO_ROOT = Path(__file__).resolve().parents[4]


def find_holosoma_python(venv: str | Path | None = None) -> Path:
    """The Holosoma interpreter: ``venv`` > $ECONMOTOR_HOLOSOMA_VENV > ./.venv-holosoma > repo's."""
    candidates = [Path(v) for v in (venv, os.environ.get(VENV_ENV)) if v]
    candidates += [Path.cwd() / ".venv-holosoma", _REPO_ROOT / ".venv-holosoma"]
    for candidate in candidates:
        python = candidate / "bin" / "python"
        if python.exists():
            return python
    raise BackendError(
        "the Holosoma environment (.venv-holosoma) is missing: run `make holosoma` in the econmotor checkout, "
        f"or `pip install -r requirements-holosoma.txt` into a venv and set {VENV_ENV} to it "
        f"(looked in: {', '.join(str(c) for c in candidates)})"
    )


class HolosomaPolicyHandle(StepAlias):
    """A Holosoma policy in onnxruntime: ``act(actor_obs) -> actions`` (``step`` is the same) plus both
    sets of metadata.

    Attributes:
        dof_names, kp, kd, action_scale: Holosoma's export metadata (joint order, PD gains,
            action scaling: joint target = default_pos + action_scale * action).
        holosoma_metadata: every Holosoma metadata entry (JSON-decoded).
        econmotor_metadata: ours: task id, objective, overlay weights, task economics.
        obs_dim, action_dim: input and output widths.
    """

    def __init__(self, onnx_path: str | Path) -> None:
        import onnxruntime as ort

        self.onnx_path = str(onnx_path)
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        self.session = ort.InferenceSession(self.onnx_path, options, providers=["CPUExecutionProvider"])
        raw = self.session.get_modelmeta().custom_metadata_map
        decoded = {k: _json_or_text(v) for k, v in raw.items()}
        self.holosoma_metadata = {k: v for k, v in decoded.items() if not k.startswith("econmotor_")}
        self.econmotor_metadata = {k[len("econmotor_"):]: v for k, v in decoded.items() if k.startswith("econmotor_")}
        self.dof_names: list[str] = list(self.holosoma_metadata.get("dof_names", []))
        self.kp = self.holosoma_metadata.get("kp")
        self.kd = self.holosoma_metadata.get("kd")
        self.action_scale = self.holosoma_metadata.get("action_scale")
        self._input = self.session.get_inputs()[0]
        self.takes_time_step = any(i.name == "time_step" for i in self.session.get_inputs())
        self.obs_dim = int(self._input.shape[-1])
        self.action_dim = int(self.session.get_outputs()[0].shape[-1])

    def act(self, obs: np.ndarray, time_step: int = 0) -> np.ndarray:
        """Actions for one observation ``[obs_dim]`` or a batch ``[n, obs_dim]`` (float32).

        Whole-body-tracking exports also take the motion clip's ``time_step`` (frame index).
        """
        x = np.asarray(obs, dtype=np.float32)
        single = x.ndim == 1
        batch = x[None, :] if single else x
        if batch.shape[-1] != self.obs_dim:
            raise BackendError(f"observation width {batch.shape[-1]} does not match the policy's {self.obs_dim}")
        outputs = []
        for row in batch:
            feed = {self._input.name: row[None, :]}
            if self.takes_time_step:
                feed["time_step"] = np.array([[time_step]], dtype=np.float32)
            outputs.append(self.session.run(None, feed)[0])
        out = np.concatenate(outputs)
        return out[0] if single else out


def _json_or_text(value: str) -> Any:
    try:
        return json.loads(value)
    except (json.JSONDecodeError, TypeError):
        return value


def attach_econmotor_metadata(onnx_path: str | Path, metadata: dict[str, Any]) -> None:
    """Add ``econmotor_<key>`` entries (JSON values) to an ONNX file's metadata, replacing old ones."""
    import onnx

    model = onnx.load(str(onnx_path))
    keep = [p for p in model.metadata_props if not p.key.startswith("econmotor_")]
    del model.metadata_props[:]
    model.metadata_props.extend(keep)
    for key, value in metadata.items():
        entry = model.metadata_props.add()
        entry.key, entry.value = f"econmotor_{key}", json.dumps(value, default=str)
    tmp = Path(str(onnx_path) + ".tmp")
    onnx.save(model, str(tmp))
    tmp.replace(onnx_path)


class HolosomaBackend:
    """Holosoma through its own interpreter (module docstring).

    Args:
        simulator: ``auto`` (default; $ECONMOTOR_HOLOSOMA_SIMULATOR overrides), ``isaacgym``,
            ``isaacsim``, ``mjwarp`` or ``mujoco`` (classic, CPU, one env).
        algo: ``ppo`` or ``fast_sac`` ($ECONMOTOR_HOLOSOMA_ALGO, else the task entry's ``algo``, else ppo).
        venv: the Holosoma virtualenv (default: see :func:`find_holosoma_python`).
        cpu_max_env_steps: cap on environment steps when training on the CPU.
        eval_episode_length_s: evaluation episode length (default: the preset's, 20 s for locomotion).
        job_timeout_s: kill a job running longer than this.
        task_files: user task catalog YAML files (added to the shipped catalog).
    """

    name = "holosoma"

    def __init__(
        self,
        simulator: str | None = None,
        algo: str | None = None,
        venv: str | Path | None = None,
        cpu_max_env_steps: int = DEFAULT_CPU_MAX_ENV_STEPS,
        eval_episode_length_s: float | None = None,
        job_timeout_s: float | None = None,
        task_files: Sequence[str | Path] = (),
    ) -> None:
        self.simulator = simulator or os.environ.get(SIMULATOR_ENV, "auto")
        # an unknown simulator name fails here, before any job starts
        choose_simulator(self.simulator, Capabilities(cuda=True, isaacgym=True, isaacsim=True, mujoco_warp=True))
        self.algo = algo or os.environ.get(ALGO_ENV) or None
        self.task_files = list(task_files)
        self.venv = venv
        self.cpu_max_env_steps = int(cpu_max_env_steps)
        self.eval_episode_length_s = eval_episode_length_s
        self.job_timeout_s = job_timeout_s
        self._caps: Capabilities | None = None

    # -- helpers ---------------------------------------------------------------------------------
    @property
    def python(self) -> Path:
        return find_holosoma_python(self.venv)

    def capabilities(self, run_dir: Path) -> Capabilities:
        """What the Holosoma interpreter can use (probed once per backend)."""
        if self._caps is None:
            outcome = run_job(self.python, {"action": "probe"}, run_dir, no_progress, self.job_timeout_s)
            self._caps = Capabilities.from_dict(outcome.result)
        return self._caps

    def _task(self, task_id: str) -> tuple[Any, dict[str, Any]]:
        spec = get_task(task_id, self.task_files)
        return spec, task_settings(task_id, spec.backend_entry("holosoma"), spec.source)

    @staticmethod
    def _overlay(objective: EconomicObjectiveSpec, gain: float) -> tuple[dict[str, float], list[str]]:
        overlay = compile_economic_overlay(objective)
        weights = {k: gain * s for k, s in overlay.items() if k in OVERLAY_TERM_KEYS}
        messages = [f"objective key '{k}' (scale {s}) has no Holosoma simulator term; ignored in training"
                    for k, s in overlay.items() if k not in OVERLAY_TERM_KEYS]
        return weights, messages

    # -- the protocol ----------------------------------------------------------------------------
    def train_policy(
        self,
        task_id: str,
        objective: EconomicObjectiveSpec,
        datapack_ids: Sequence[str],
        num_envs: int,
        max_steps: int,
        seed: int,
        *,
        datapack_configs: Sequence[DatapackConfig] | None = None,
        output_dir: str | Path | None = None,
        eval_episodes: int = 5,
        progress: ProgressFn = no_progress,
    ) -> MotorTrainingResult:
        """Train with Holosoma (plus the econ overlay), then evaluate ``eval_episodes`` episodes."""
        spec, settings = self._task(task_id)
        algo = self.algo or settings.get("algo", "ppo")
        if algo not in settings["experiment"]:
            raise ConfigError(spec.source, f"tasks.{task_id}.backends.holosoma.experiment",
                              f"no Holosoma preset for algorithm '{algo}'", list(settings["experiment"]))
        packs = list(datapack_configs or ())
        bundle = DatapackProvider().resolve(task_id, list(datapack_ids), packs)
        overrides = map_datapacks(bundle, packs, uses_motion_clip=bool(settings["uses_motion_clip"]))
        if overrides.motion_duration_s is not None:  # a unit of work is one pass through the clip
            settings = {**settings, "unit_duration_s": overrides.motion_duration_s}
        weights, messages = self._overlay(objective, float(settings["overlay_gain"]))
        run_dir = Path(output_dir or Path(".econmotor") / "holosoma_runs") / (
            f"{task_id}-{time.strftime('%Y%m%d-%H%M%S')}-seed{seed}")
        run_dir = run_dir.resolve()
        simulator, device = choose_simulator(self.simulator, self.capabilities(run_dir))
        plan = plan_training(experiment=settings["experiment"][algo], algo=algo, simulator=simulator, device=device,
                             num_envs=num_envs, max_steps=max_steps, cpu_max_env_steps=self.cpu_max_env_steps)
        messages = [*plan.messages, *overrides.messages, *messages]
        for text in messages:
            progress(f"holosoma: {text}", 1.0, 1.0)
        overlay_params = {k: settings[k] for k in ("progress_mode", "unit_length_m", "unit_duration_s",
                                                   "max_tilt_rad", "novelty_rate")}
        overlay_params["efficiency"] = float(settings["drivetrain_efficiency"])
        job = {
            "action": "train", "run_dir": str(run_dir), "run_name": f"{task_id}-seed{seed}",
            "experiment": plan.experiment, "algo": algo, "simulator": plan.simulator, "device": plan.device,
            "num_envs": plan.num_envs, "iterations": plan.iterations, "seed": int(seed), "cpu_sized": plan.cpu_sized,
            "motion_task": bool(settings["uses_motion_clip"]),
            "overlay": {"weights": weights, "params": overlay_params}, "overrides": overrides.to_dict(),
        }
        outcome = run_job(self.python, job, run_dir, progress, self.job_timeout_s)
        messages += list(outcome.messages)
        result = outcome.result
        if not result.get("checkpoint") or not result.get("onnx"):
            raise BackendError(f"Holosoma finished without a checkpoint and ONNX export in {result['experiment_dir']}")
        ours = {"task_id": task_id, "objective": objective.to_dict(), "overlay_weights": weights,
                "overlay_gain": settings["overlay_gain"], "task_economics": spec.economics.to_dict(),
                "settings": settings}
        attach_econmotor_metadata(result["onnx"], ours)
        manifest = {**ours, "checkpoint": result["checkpoint"], "onnx": result["onnx"],
                    "experiment_dir": result["experiment_dir"], "episode_length_s": result["episode_length_s"],
                    "control_dt_s": result["control_dt_s"], "simulator": plan.simulator, "algo": algo}
        (run_dir / MANIFEST).write_text(json.dumps(manifest, indent=2, default=str), encoding="utf-8")
        curve = [{"timesteps": float(c["timesteps"]), "mean_return": float(c["mean_return"])}
                 for c in outcome.curve if c.get("mean_return") is not None]
        econ_log = {k: v for c in outcome.curve for k, v in c.get("econ", {}).items()}
        raw: dict[str, float] = {}
        econ: dict[str, float] = {}
        episodes: list[dict[str, Any]] = []
        config: dict[str, Any] = {
            "seed": seed, "objective": objective.to_dict(), "datapacks": list(bundle.datapack_ids),
            "overrides": overrides.to_dict(), "plan": {**plan.__dict__, "messages": list(plan.messages)},
            "overlay_weights": weights, "messages": messages, "econ_term_log": econ_log,
            "reward_terms": result["reward_terms"], "train_wall_s": outcome.wall_s,
            "econ_term_seconds": result.get("econ_term_seconds", 0.0),
            "iteration_times_s": [{"collection_s": c.get("collection_s"), "learn_s": c.get("learn_s")}
                                  for c in outcome.curve],
        }
        if eval_episodes > 0:
            ev = self.evaluate_policy(str(run_dir), task_id, objective, eval_episodes, seed,
                                      datapack_configs=datapack_configs, output_dir=run_dir / "eval", progress=progress)
            raw, econ, episodes = ev.raw_metrics, ev.econ_metrics, ev.episodes
            config["evaluation"] = ev.config
        artifacts = {"policy": str(run_dir), "checkpoint": result["checkpoint"], "onnx": result["onnx"],
                     "tensorboard": result["experiment_dir"], "train_log": outcome.log_path}
        return MotorTrainingResult(str(run_dir), task_id, self.name, raw, econ, episodes, curve, config, artifacts)

    def evaluate_policy(
        self,
        policy_id: str,
        task_id: str,
        objective: EconomicObjectiveSpec,
        num_episodes: int,
        seed: int,
        *,
        datapack_configs: Sequence[DatapackConfig] | None = None,
        output_dir: str | Path | None = None,
        progress: ProgressFn = no_progress,
    ) -> MotorEvalResult:
        """Holosoma's eval_agent with recording; econ metrics from the recording's episodes."""
        if num_episodes < 1:
            raise ConfigError("<evaluate>", "num_episodes", f"must be >= 1, got {num_episodes}")
        manifest = self._manifest(policy_id)
        spec = get_task(task_id, self.task_files)
        settings = manifest["settings"]  # the physical parameters the policy was trained with
        episode_s = float(self.eval_episode_length_s or manifest["episode_length_s"])
        steps = num_episodes * math.ceil(episode_s / float(manifest["control_dt_s"]))
        run_dir = Path(output_dir or Path(policy_id) / f"eval-{time.strftime('%Y%m%d-%H%M%S')}").resolve()
        simulator = self._eval_simulator(manifest.get("simulator", "mujoco"), run_dir, progress)
        job = {"action": "evaluate", "run_dir": str(run_dir), "checkpoint": manifest["checkpoint"],
               "num_steps": steps, "episode_length_s": episode_s, "seed": int(seed), "simulator": simulator}
        outcome = run_job(self.python, job, run_dir, progress, self.job_timeout_s)
        raw_episodes = episodes_from_recording(outcome.result["recording"], settings, num_episodes)
        if not raw_episodes:
            raise BackendError(f"Holosoma's recording {outcome.result['recording']} holds no steps")
        raw, econ, episodes = summarize_episodes(raw_episodes, spec.economics)
        config = {"seed": seed, "objective": objective.to_dict(), "recording": outcome.result["recording"],
                  "exported_onnx": outcome.result.get("onnx"), "episode_length_s": episode_s, "num_steps": steps,
                  "messages": list(outcome.messages), "eval_log": outcome.log_path}
        return MotorEvalResult(policy_id, task_id, self.name, raw, econ, episodes, config)

    def _eval_simulator(self, trained_on: str, run_dir: Path, progress: ProgressFn) -> str:
        """The training simulator when this machine has it (or the one asked for), else the auto choice."""
        caps = self.capabilities(run_dir)
        wanted = trained_on if self.simulator == "auto" else self.simulator
        try:
            return choose_simulator(wanted, caps)[0]
        except ConfigError:
            fallback = choose_simulator("auto", caps)[0]
            progress(f"holosoma: evaluating on {fallback}: the policy was trained on {wanted}, "
                     "which this machine cannot run", 1.0, 1.0)
            return fallback

    def deploy_policy_handle(self, policy_id: str) -> HolosomaPolicyHandle:
        """An onnxruntime handle for a trained run directory (or an ONNX file)."""
        path = Path(policy_id)
        onnx_path = path if path.suffix == ".onnx" else Path(self._manifest(policy_id)["onnx"])
        if not onnx_path.is_file():
            raise BackendError(f"no ONNX policy at {onnx_path}")
        return HolosomaPolicyHandle(onnx_path)

    @staticmethod
    def _manifest(policy_id: str) -> dict[str, Any]:
        path = Path(policy_id) / MANIFEST
        if not path.is_file():
            raise BackendError(f"{policy_id} is not a Holosoma run directory (no {MANIFEST}); "
                               "pass the policy_id that train_policy returned")
        return json.loads(path.read_text(encoding="utf-8"))

