"""The job runner: ``python -m econmotor.motor_backend.holosoma.venv.runner JOB.json`` in .venv-holosoma.

A job is one of :mod:`.job_specs`' dataclasses, written as JSON by :mod:`.host.jobs` in the main
interpreter and parsed here once (:func:`.job_specs.parse_job`; a bad job is a ConfigError the caller
raises again):

- :class:`.job_specs.ProbeJob`: report CUDA and which simulators import.
- :class:`.job_specs.TrainJob`: build the Holosoma experiment config from a preset
  (simulator, envs, iterations, CPU-sized algorithm settings, the econ overlay reward
  terms, datapack randomization/curriculum/terrain/motion overrides) and run Holosoma's
  own ``train_agent.train``; report each iteration and the checkpoint / ONNX paths.
- :class:`.job_specs.EvaluateJob`: run Holosoma's ``eval_agent`` on a checkpoint with
  the (extended) recording callback; report the recording and exported ONNX paths.

Results and progress go out as protocol lines (:mod:`.protocol`); Holosoma's own
log lines pass through untouched so the parent can surface its error text.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import os
import sys
import traceback
from pathlib import Path
from typing import Any

from econmotor.errors import ConfigError
from econmotor.motor_backend.holosoma.job_specs import (
    EvaluateJob,
    HolosomaJob,
    Overlay,
    TrainJob,
    parse_job,
)
from econmotor.motor_backend.holosoma.protocol import emit

OVERLAY_TERM = "econmotor.motor_backend.holosoma.venv.reward_terms:EconOverlayTerm"
RECORDING_TARGET = "econmotor.motor_backend.holosoma.venv.recording.EconRecordingCallback"
PROJECT = "econmotor"
MATERIAL_TERM = "randomize_robot_rigid_body_material_startup"


def probe() -> dict[str, Any]:
    import torch

    return {
        "cuda": bool(torch.cuda.is_available()),
        "isaacgym": importlib.util.find_spec("isaacgym") is not None,
        "isaacsim": importlib.util.find_spec("isaacsim") is not None,
        "mujoco_warp": importlib.util.find_spec("mujoco_warp") is not None,
        "torch": torch.__version__,
    }


def _merge_term(terms: dict[str, Any], name: str, params: dict[str, Any], where: str) -> dict[str, Any]:
    if name not in terms:
        raise ValueError(f"{where}: the preset has no term '{name}' (it has: {', '.join(sorted(terms))})")
    term = terms[name]
    return {**terms, name: dataclasses.replace(term, params={**dict(term.params), **params})}


def _algo_config(cfg: Any, job: TrainJob) -> Any:
    algo = cfg.algo.config
    iterations = job.plan.iterations
    if job.plan.algo == "ppo":
        return dataclasses.replace(algo, num_learning_iterations=iterations, save_interval=max(iterations, 1))
    changes: dict[str, Any] = {"num_learning_iterations": iterations, "save_interval": 0,
                               "logging_interval": max(1, iterations // 20)}
    if job.plan.cpu_sized:
        changes.update(batch_size=256, compile=False, amp=False)
    return dataclasses.replace(algo, **changes)


def _reward_config(cfg: Any, overlay: Overlay) -> Any:
    from holosoma.config_types.reward import RewardTermCfg

    terms = dict(cfg.reward.terms)
    for key, weight in overlay.weights.items():
        terms[f"econ_{key}"] = RewardTermCfg(func=OVERLAY_TERM, params={"key": key, **overlay.params},
                                             weight=float(weight), tags=["econ_overlay"])
    return dataclasses.replace(cfg.reward, terms=terms)


def _simulator_name(cfg: Any) -> str:
    from holosoma.config_values.simulator import SIMULATOR_REGISTRY

    return next((name for name, sim in SIMULATOR_REGISTRY.items() if sim._target_ == cfg.simulator._target_
                 and sim.config.mujoco_backend == cfg.simulator.config.mujoco_backend), cfg.simulator.config.name)


def _simulator(name: str, cfg: Any) -> Any:
    """Registry simulator ``name`` with the episode length of ``cfg``'s simulator."""
    from holosoma.config_values.simulator import SIMULATOR_REGISTRY

    sim = SIMULATOR_REGISTRY[name]
    episode_s = cfg.simulator.config.sim.max_episode_length_s
    return dataclasses.replace(sim, config=dataclasses.replace(
        sim.config, sim=dataclasses.replace(sim.config.sim, max_episode_length_s=episode_s)))


def build_train_config(job: TrainJob) -> Any:
    """The Holosoma ExperimentConfig of a train job (preset + every override)."""
    from holosoma.config_types.logger import DisabledLoggerConfig
    from holosoma.config_values.experiment import EXPERIMENT_REGISTRY
    from holosoma.config_values.terrain import TERRAIN_REGISTRY

    cfg = EXPERIMENT_REGISTRY[job.plan.experiment]
    sim = _simulator(job.plan.simulator, cfg)
    over = job.overrides
    randomization = cfg.randomization
    if over["randomization"]:
        setup = dict(randomization.setup_terms)
        for term, params in over["randomization"].items():
            if term == "randomize_friction_startup" and term not in setup and MATERIAL_TERM in setup:
                # whole-body tracking presets randomize friction through the rigid-body material term
                term = MATERIAL_TERM
                params = {"static_friction_range": params["friction_range"],
                          "dynamic_friction_range": params["friction_range"]}
            setup = _merge_term(setup, term, params, f"datapack domain_randomization -> randomization '{term}'")
        randomization = dataclasses.replace(randomization, setup_terms=setup)
    if job.plan.simulator in ("mujoco", "mjwarp") and job.motion_task:
        randomization = dataclasses.replace(randomization, ignore_unsupported=True)
        emit("message", text="randomization.ignore_unsupported=True: some whole-body-tracking randomizers "
                             "have no MuJoCo implementation and are skipped")
    curriculum = cfg.curriculum
    if over["curriculum"] and "penalty_curriculum" not in curriculum.setup_terms:
        emit("message", text=f"datapack curriculum ignored: preset {job.plan.experiment} has no PenaltyCurriculum "
                             f"(its curriculum terms: {', '.join(sorted(curriculum.setup_terms))})")
    elif over["curriculum"]:
        setup = _merge_term(dict(curriculum.setup_terms), "penalty_curriculum", over["curriculum"],
                            "datapack curriculum -> PenaltyCurriculum")
        curriculum = dataclasses.replace(curriculum, setup_terms=setup)
    command = cfg.command
    if over["motion_file"]:
        term = command.setup_terms["motion_command"]
        motion = term.params["motion_config"]
        motion = (dataclasses.replace(motion, motion_file=over["motion_file"]) if dataclasses.is_dataclass(motion)
                  else {**motion, "motion_file": over["motion_file"]})
        command = dataclasses.replace(command, setup_terms={
            **command.setup_terms, "motion_command": dataclasses.replace(term, params={**term.params,
                                                                                      "motion_config": motion})})
    terrain = TERRAIN_REGISTRY[over["terrain"]] if over["terrain"] else cfg.terrain
    return dataclasses.replace(
        cfg,
        simulator=sim,
        training=dataclasses.replace(cfg.training, num_envs=job.plan.num_envs, seed=job.seed,
                                     project=PROJECT, name=job.run_name, headless=True, export_onnx=True),
        logger=DisabledLoggerConfig(base_dir=str(Path(job.run_dir) / "holosoma")),
        algo=dataclasses.replace(cfg.algo, config=_algo_config(cfg, job)),
        reward=_reward_config(cfg, job.overlay),
        randomization=randomization,
        curriculum=curriculum,
        command=command,
        terrain=terrain,
    )


def _report_iterations(total: int) -> None:
    """Wrap Holosoma's per-iteration logging to also emit progress and the training curve."""
    from holosoma.agents.modules.logging_utils import LoggingHelper

    original = LoggingHelper._logging_to_writer

    def logging_to_writer(self: Any, it: int, *args: Any, **kwargs: Any) -> Any:
        scalars = kwargs.get("ep_scalars_to_log") or {}
        rewards = list(self.rewbuffer)
        emit("curve", iteration=int(it), timesteps=int(self.tot_timesteps),
             collection_s=float(self.collection_time), learn_s=float(self.learn_time),
             mean_return=(sum(rewards) / len(rewards)) if rewards else None,
             econ={k: float(v) for k, v in scalars.items() if "econ_" in k})
        emit("progress", label="holosoma train", done=min(int(it) + 1, total), total=total)
        return original(self, it, *args, **kwargs)

    LoggingHelper._logging_to_writer = logging_to_writer


def _latest(paths: list[Path]) -> Path | None:
    def number(p: Path) -> int:
        digits = "".join(ch for ch in p.stem if ch.isdigit())
        return int(digits) if digits else -1

    return max(paths, key=number) if paths else None


def train(job: TrainJob) -> dict[str, Any]:
    from holosoma.train_agent import train as holosoma_train

    cfg = build_train_config(job)
    emit("message", text=f"Holosoma {job.plan.experiment} on {job.plan.simulator} ({job.plan.device}): "
                         f"{job.plan.num_envs} env(s), {job.plan.iterations} {job.plan.algo} iteration(s), "
                         f"econ terms {sorted(job.overlay.weights)}")
    _report_iterations(job.plan.iterations)
    holosoma_train(cfg)
    runs = sorted((Path(job.run_dir) / "holosoma" / PROJECT).glob("*"))
    if not runs:
        raise RuntimeError(f"Holosoma wrote no experiment directory under {Path(job.run_dir) / 'holosoma'}")
    exp_dir = runs[-1]
    checkpoint = _latest(list(exp_dir.glob("model_*.pt")))
    onnx = checkpoint.with_suffix(".onnx") if checkpoint is not None else None
    terms_module = sys.modules.get("econmotor.motor_backend.holosoma.venv.reward_terms")
    timer = dict(terms_module.TIMER) if terms_module is not None else {"seconds": 0.0, "calls": 0}
    return {"econ_term_seconds": timer["seconds"], "econ_term_calls": timer["calls"],
            "experiment_dir": str(exp_dir), "checkpoint": str(checkpoint) if checkpoint else None,
            "onnx": str(onnx) if onnx is not None and onnx.exists() else None,
            "reward_terms": sorted(cfg.reward.terms), "episode_length_s": cfg.simulator.config.sim.max_episode_length_s,
            "control_dt_s": cfg.simulator.config.sim.control_decimation_steps / cfg.simulator.config.sim.fps}


def evaluate(job: EvaluateJob) -> dict[str, Any]:
    from holosoma.config_types.eval_callback import (
        EvalCallbacksConfig,
        RecordingCallbackConfig,
        RecordingConfig,
    )
    from holosoma.config_types.experiment import EvalOverridesConfig
    from holosoma.config_types.logger import DisabledLoggerConfig
    from holosoma.eval_agent import run_eval_with_tyro
    from holosoma.utils.eval_utils import (
        CheckpointConfig,
        init_eval_logging,
        load_saved_experiment_config,
    )

    init_eval_logging()
    checkpoint = CheckpointConfig(checkpoint=job.checkpoint)
    saved, wandb_path = load_saved_experiment_config(checkpoint)
    overrides = EvalOverridesConfig(headless=True, num_envs=1, disable_logger=True,
                                    max_episode_length_s=float(job.episode_length_s))
    saved_for_eval = dataclasses.replace(saved, eval_overrides=overrides)
    if job.simulator and job.simulator != _simulator_name(saved):
        saved_for_eval = dataclasses.replace(saved_for_eval, simulator=_simulator(job.simulator, saved))
    cfg = saved_for_eval.get_eval_config()
    cfg = dataclasses.replace(
        cfg,
        training=dataclasses.replace(cfg.training, max_eval_steps=job.num_steps, seed=job.seed,
                                     export_onnx=True, project=PROJECT, name="eval"),
        logger=DisabledLoggerConfig(base_dir=str(Path(job.run_dir) / "holosoma_eval")),
    )
    recording_path = str(Path(job.run_dir) / "eval_recording.npz")
    callbacks = EvalCallbacksConfig(recording=RecordingCallbackConfig(
        _target_=RECORDING_TARGET, config=RecordingConfig(enabled=True, output_path=recording_path)))
    os.environ["ECONMOTOR_EVAL_STEPS"] = str(job.num_steps)
    emit("message", text=f"Holosoma eval_agent: {job.num_steps} steps on {_simulator_name(cfg)}, "
                         f"episodes of {job.episode_length_s} s, recording to {recording_path}")
    run_eval_with_tyro(cfg, checkpoint, saved, wandb_path, eval_cbs_cfg=callbacks)
    ckpt = Path(job.checkpoint)
    onnx = ckpt.parent / "exported" / ckpt.with_suffix(".onnx").name
    if not Path(recording_path).is_file():
        raise RuntimeError(f"Holosoma's evaluation wrote no recording at {recording_path}")
    return {"recording": recording_path, "onnx": str(onnx) if onnx.is_file() else None}


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        sys.stderr.write("usage: python -m econmotor.motor_backend.holosoma.venv.runner JOB.json\n")
        return 2
    os.environ.setdefault("WANDB_MODE", "disabled")
    actions = {"probe": lambda _job: probe(), "train": train, "evaluate": evaluate}
    try:
        job: HolosomaJob = parse_job(Path(argv[0]).read_text(encoding="utf-8"), argv[0])
        import torch

        torch.set_num_threads(int(os.environ.get("OMP_NUM_THREADS", "1")))
        result = actions[job.action](job)
    except ConfigError as exc:  # bad input (e.g. an imported policy's metadata): the caller raises it again
        emit("error", text=f"{type(exc).__name__}: {exc}", config_error=[exc.source, exc.key, exc.detail, exc.allowed])
        return 1
    except Exception as exc:
        emit("error", text=f"{type(exc).__name__}: {exc}", traceback=traceback.format_exc())
        return 1
    emit("result", **result)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
