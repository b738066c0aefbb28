"""Importing a locomotion policy trained elsewhere: the contract between an ONNX file and MuJoCo.

A policy is named by an ONNX file in Holosoma's export format (metadata ``dof_names``,
``kp``, ``kd``, ``command_ranges``) or by a shipped policy, ``holosoma:<robot>/<algo>``
(``holosoma:g1_29dof/ppo``, ``holosoma:t1_29dof/fastsac``, ...: the ONNX files under
``holosoma_inference/models/loco/``). :func:`resolve_contract` reads, in this order:

1. the ONNX metadata: joint order, PD gains, command ranges, input name and width;
2. holosoma_inference's inference preset whose robot has those joints: observation terms,
   dimensions, scales, history length, the (sorted) order the terms are concatenated in,
   gait phase (``use_phase``, ``gait_period``), control rate, default pose, action scale;
3. Holosoma's experiment preset for that robot: the MJCF, effort limits, initial base
   height, torso body, physics rate and decimation.

Nothing is copied: every number comes from the installed packages. Name parsing
(:func:`parse_policy_name`, :func:`is_imported_policy`), finding a shipped file
(:func:`shipped_policy_path`, without importing holosoma_inference) and the metadata a policy
trained here is exported with (:func:`holosoma_export_metadata`) import nothing and run in the
main interpreter; :func:`resolve_contract` runs in .venv-holosoma.

The export format (Holosoma 0.0.3's ``PPO.export``): input ``actor_obs``, output ``action``, and
JSON metadata entries ``dof_names``, ``kp``, ``kd``, ``action_scale``, ``command_ranges``,
``observation_layout`` (one entry per term in concatenation order: ``group``, ``name``, ``func``,
``dim``, ``history_length``, ``scale``, ``clip``, ``params``) and ``observation_clip``; the
shipped walkers, exported by an older Holosoma, carry the first four only. Holosoma's exporter
also writes its training configuration and URDF (``experiment_config``, ``robot_urdf``), which a
policy trained here does not have; holosoma_inference's locomotion policies read neither.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from econmotor.errors import ConfigError

#: ``holosoma:<robot>/<algo>`` (the shipped locomotion policies)
NAME_PREFIX = "holosoma:"
_NAME = re.compile(r"^holosoma:([A-Za-z0-9_]+)/([A-Za-z0-9_]+)$")
#: algorithm spellings -> the file prefix under holosoma_inference/models/loco/<robot>/
ALGO_FILE_PREFIX = {"ppo": "ppo", "fastsac": "fastsac", "fast_sac": "fastsac"}
REQUIRED_METADATA = ("dof_names", "kp", "kd")
#: the module of Holosoma's locomotion observation terms (``ObsTermCfg.func`` is ``<module>:<term>``)
LOCO_TERMS_MODULE = "holosoma.managers.observation.terms.locomotion"


def holosoma_export_metadata(card: Any, observation_clip: float | None = None) -> dict[str, Any]:
    """Holosoma's export metadata (module docstring) of a robot card (``econmotor.robots``): joints, PD
    gains, action scale, command ranges and the ``actor_obs`` layout. ``observation_clip``: the clip the
    observations were trained with (None: not clipped)."""
    conv = card.observation
    layout = [{"group": "actor_obs", "name": term, "func": f"{LOCO_TERMS_MODULE}:{term}", "dim": int(conv.dims[term]),
               "history_length": int(conv.history_length), "scale": float(conv.scales[term]), "clip": None,
               "params": {}} for term in conv.terms]
    return {"dof_names": list(card.dof_names), "kp": [float(v) for v in card.kp], "kd": [float(v) for v in card.kd],
            "action_scale": float(card.action_scale),
            "command_ranges": {k: [float(v) for v in r] for k, r in card.command_ranges.items()},
            "observation_layout": layout, "observation_clip": observation_clip}


def is_imported_policy(policy_id: str) -> bool:
    """True for a shipped policy name or an ``.onnx`` file (not a run directory)."""
    return str(policy_id).startswith(NAME_PREFIX) or str(policy_id).endswith(".onnx")


def parse_policy_name(name: str, flag: str = "--policy") -> tuple[str, str]:
    """``holosoma:<robot>/<algo>`` -> ``(robot, algo)``; a ConfigError (naming ``flag``) shows the form and
    the algorithms."""
    match = _NAME.match(name)
    if not match or match.group(2) not in ALGO_FILE_PREFIX:
        raise ConfigError(flag, name, "a shipped policy is named holosoma:<robot>/<algo>",
                          [f"holosoma:{r}/{a}" for r in ("g1_29dof", "t1_29dof") for a in ("ppo", "fastsac")])
    return match.group(1), match.group(2)


@dataclass(frozen=True)
class PolicyContract:
    """Everything the sim-to-sim evaluator needs to run one imported policy (see the module docstring).

    Joint-indexed tuples follow ``dof_names`` (the ONNX order). ``obs_terms`` is the
    concatenation order (holosoma_inference sorts a group's term names).
    """

    policy: str
    onnx_path: str
    input_name: str
    obs_dim: int
    action_dim: int
    dof_names: tuple[str, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    default_dof_angles: tuple[float, ...]
    effort_limits: tuple[float, ...]
    action_scale: float
    action_clip: float
    command_ranges: dict[str, list[float]]
    obs_terms: tuple[str, ...]
    obs_dims: dict[str, int]
    obs_scales: dict[str, float]
    history_length: int
    use_phase: bool
    gait_period_s: float
    control_rate_hz: float
    physics_dt_s: float
    decimation: int
    init_pos: tuple[float, float, float]
    xml_path: str
    torso_body: str
    inference_preset: str
    experiment: str

    @property
    def control_dt_s(self) -> float:
        return self.physics_dt_s * self.decimation

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def shipped_policy_path(name: str, python: str | Path | None = None, flag: str = "--policy") -> Path:
    """The ONNX file of ``holosoma:<robot>/<algo>`` under holosoma_inference's ``models/loco/``, found
    without importing it: in the interpreter ``python``'s site-packages (the holosoma backend passes
    .venv-holosoma's), or with ``python`` None in this interpreter's. A ConfigError naming ``flag``
    lists the shipped names found, or says holosoma_inference is not installed there."""
    import importlib.util

    robot, algo = parse_policy_name(name, flag)
    file = f"{ALGO_FILE_PREFIX[algo]}_{robot}.onnx"
    if python is None:
        spec = importlib.util.find_spec("holosoma_inference")
        roots = [Path(p) / "models" / "loco" for p in (spec.submodule_search_locations or ())] if spec else []
        where = "this interpreter"
    else:
        venv = Path(python).parent.parent
        roots = sorted((venv / "lib").glob("python3*/site-packages/holosoma_inference/models/loco"))
        where = str(venv)
    found = [root / robot / file for root in roots if (root / robot / file).is_file()]
    if not found:
        shipped = sorted(f"{NAME_PREFIX}{p.parent.name}/{p.stem.split('_', 1)[0]}"
                         for root in roots for p in root.glob("*/*.onnx"))
        why = f"holosoma_inference in {where} ships no {file}" if roots else \
            f"holosoma_inference (the shipped policies) is not installed in {where}"
        raise ConfigError(flag, name, why, shipped or None)
    return found[0]


def onnx_metadata(path: str | Path) -> dict[str, Any]:
    """The ONNX file's metadata, JSON-decoded where it is JSON."""
    import onnx

    model = onnx.load(str(path), load_external_data=False)
    out: dict[str, Any] = {}
    for prop in model.metadata_props:
        try:
            out[prop.key] = json.loads(prop.value)
        except json.JSONDecodeError:
            out[prop.key] = prop.value
    return out


def _inference_preset(dof_names: Sequence[str], source: str) -> tuple[str, Any]:
    """The holosoma_inference locomotion preset whose robot has exactly these joints, in this order."""
    from holosoma_inference.config.config_values.inference import INFERENCE_REGISTRY

    candidates = {k: v for k, v in INFERENCE_REGISTRY.items() if v.task.use_phase}  # locomotion presets
    for key, cfg in candidates.items():
        if tuple(cfg.robot.dof_names) == tuple(dof_names):
            return key, cfg
    for key, cfg in candidates.items():  # same joints, another order: say so
        if sorted(cfg.robot.dof_names) == sorted(dof_names):
            raise ConfigError(source, "dof_names", f"the joints of preset '{key}' in another order "
                              f"(policy: {list(dof_names)}; preset: {list(cfg.robot.dof_names)})")
    raise ConfigError(source, "dof_names", f"no holosoma_inference locomotion preset has the policy's "
                      f"{len(dof_names)} joints {list(dof_names)[:4]}...",
                      [f"{k} ({len(v.robot.dof_names)} joints: {', '.join(v.robot.dof_names[:2])}, ...)"
                       for k, v in candidates.items()])


def _experiment(robot_type: str, dof_names: Sequence[str], source: str) -> tuple[str, Any]:
    """Holosoma's (PPO) locomotion experiment for ``robot_type``: robot config and simulator rates."""
    from holosoma.config_values.experiment import EXPERIMENT_REGISTRY

    names = sorted(EXPERIMENT_REGISTRY.keys(), key=len)  # "g1_29dof" before "g1_29dof_fast_sac"
    for name in names:
        cfg = EXPERIMENT_REGISTRY[name]
        if cfg.robot.asset.robot_type == robot_type and sorted(cfg.robot.dof_names) == sorted(dof_names):
            return name, cfg
    raise ConfigError(source, "dof_names", f"no Holosoma experiment preset for robot '{robot_type}'",
                      sorted({EXPERIMENT_REGISTRY[n].robot.asset.robot_type for n in names}))


def _resolve_asset(root: str, relative: str) -> Path:
    if root.startswith("@"):
        import importlib

        package, _, rest = root[1:].partition("/")
        root = str(Path(importlib.import_module(package).__file__).parent / rest)
    return Path(root) / relative


def resolve_contract(policy: str) -> PolicyContract:
    """The :class:`PolicyContract` of a shipped policy name or an ONNX file (module docstring)."""
    import onnxruntime as ort

    path = shipped_policy_path(policy) if policy.startswith(NAME_PREFIX) else Path(policy)
    if not path.is_file():
        raise ConfigError("--policy", policy, "no such ONNX file")
    source = str(path)
    meta = onnx_metadata(path)
    missing = [k for k in REQUIRED_METADATA if k not in meta]
    if missing:
        raise ConfigError(source, "metadata", f"lacks Holosoma export metadata {missing}", REQUIRED_METADATA)
    dof_names = tuple(str(n) for n in meta["dof_names"])
    for key in ("kp", "kd"):
        if len(meta[key]) != len(dof_names):
            raise ConfigError(source, key, f"{len(meta[key])} gains for {len(dof_names)} dof_names")
    preset_name, preset = _inference_preset(dof_names, source)
    experiment_name, experiment = _experiment(preset.robot.robot_type, dof_names, source)
    robot = experiment.robot
    by_name = dict(zip(robot.dof_names, robot.dof_effort_limit_list, strict=True))
    obs = preset.observation
    group = "actor_obs"
    terms = tuple(sorted(obs.obs_dict[group]))  # holosoma_inference concatenates a group's terms sorted
    sim = experiment.simulator.config.sim
    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    inp, out = session.get_inputs()[0], session.get_outputs()[0]
    contract = PolicyContract(
        policy=policy, onnx_path=str(path.resolve()), input_name=inp.name,
        obs_dim=int(inp.shape[-1]), action_dim=int(out.shape[-1]), dof_names=dof_names,
        kp=tuple(float(v) for v in meta["kp"]), kd=tuple(float(v) for v in meta["kd"]),
        default_dof_angles=tuple(float(v) for v in preset.robot.default_dof_angles),
        effort_limits=tuple(float(by_name[n]) for n in dof_names),
        action_scale=float(preset.task.policy_action_scale),
        action_clip=float(robot.control.action_clip_value),
        command_ranges={k: list(v) for k, v in (meta.get("command_ranges") or {}).items()},
        obs_terms=terms, obs_dims={t: int(obs.obs_dims[t]) for t in terms},
        obs_scales={t: float(obs.obs_scales[t]) for t in terms},
        history_length=int(obs.history_length_dict.get(group, 1)),
        use_phase=bool(preset.task.use_phase), gait_period_s=float(preset.task.gait_period),
        control_rate_hz=float(preset.task.rl_rate), physics_dt_s=1.0 / float(sim.fps),
        decimation=int(sim.control_decimation_steps),
        init_pos=tuple(float(v) for v in robot.init_state.pos),
        xml_path=str(_resolve_asset(robot.asset.asset_root, robot.asset.xml_file)),
        torso_body=str(robot.torso_name), inference_preset=preset_name, experiment=experiment_name)
    check_obs_size(contract, source)
    if abs(contract.control_dt_s * contract.control_rate_hz - 1.0) > 1e-6:
        raise ConfigError(source, "rl_rate", f"holosoma_inference runs the policy at {contract.control_rate_hz} Hz "
                          f"but Holosoma trained it at {1 / contract.control_dt_s:g} Hz "
                          f"({sim.fps} Hz physics / {sim.control_decimation_steps})")
    return contract


def check_obs_size(contract: PolicyContract, source: str) -> None:
    """The preset's observation width must equal the ONNX input's; else a ConfigError naming both."""
    width = sum(contract.obs_dims[t] for t in contract.obs_terms) * contract.history_length
    if width != contract.obs_dim:
        parts = " + ".join(f"{t} {contract.obs_dims[t]}" for t in contract.obs_terms)
        raise ConfigError(source, f"input '{contract.input_name}'",
                          f"the ONNX policy takes {contract.obs_dim} observations but preset "
                          f"'{contract.inference_preset}' builds {width} ({parts}; history {contract.history_length})")
    if contract.action_dim != len(contract.dof_names):
        raise ConfigError(source, "dof_names", f"the ONNX policy outputs {contract.action_dim} actions for "
                          f"{len(contract.dof_names)} dof_names")


def check_dof_names(dof_names: Sequence[str], joints: Sequence[str], actuators: Sequence[str], model: str,
                    source: str) -> None:
    """Every policy joint must be a hinge joint and an actuator of the MuJoCo model; else a ConfigError
    naming the policy's missing joints and the model's joints (both sides)."""
    for kind, names in (("joints", joints), ("actuators", actuators)):
        missing = [n for n in dof_names if n not in names]
        if missing:
            raise ConfigError(source, "dof_names", f"policy joints {missing} are not {kind} of the MuJoCo model "
                              f"{model} (policy: {len(dof_names)} dof_names; model {kind}: {list(names)})")
