"""Importing a locomotion policy trained elsewhere: the contract between an ONNX file and its robot's card.

A policy is named by an ONNX file in Holosoma's export format (metadata ``dof_names``,
``kp``, ``kd``, ``command_ranges``) or by a shipped policy, ``holosoma:<robot>/<algo>``
(``holosoma:g1_29dof/ppo``, ``holosoma:t1_29dof/fastsac``, ...: the ONNX files under
``holosoma_inference/models/loco/``). :func:`resolve_contract` reads:

1. the ONNX: joint order, PD gains and command ranges (an imported policy declares its gains),
   input name and width;
2. the robot card whose joints those are, in that order (:mod:`econmotor.robots`): the MJCF,
   default pose, action scale and clip, effort limits, torso, fall rule, collision filter, physics
   rate and decimation, and the observation convention (terms, scales, order, gait phase).

Name parsing (:func:`parse_policy_name`, :func:`is_imported_policy`), finding a shipped file
(:func:`shipped_policy_path`, without importing holosoma_inference) and the metadata a policy
trained here is exported with (:func:`holosoma_export_metadata`) import nothing and run in the
main interpreter; :func:`resolve_contract` runs in either (a shipped name needs
holosoma_inference's files: the main interpreter installs them with ``--no-deps``, else
.venv-holosoma's are read).

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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from econmotor.couriers.onnx_file import load_onnx, onnx_session
from econmotor.errors import BackendError, ConfigError
from econmotor.robots import CARDS, RobotCard

#: the environment variable naming Holosoma's interpreter's venv (the CLI passes it to the backends)
VENV_ENV = "ECONMOTOR_HOLOSOMA_VENV"
_REPO_ROOT = Path(__file__).resolve().parents[3]
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


def find_holosoma_python(venv: str | Path | None = None) -> Path:
    """The Holosoma interpreter: ``venv`` (the CLI passes $ECONMOTOR_HOLOSOMA_VENV) > ./.venv-holosoma > repo's."""
    candidates = [Path(venv)] if venv else []
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


def is_imported_policy(policy_id: str) -> bool:
    """True for a shipped policy name or an ``.onnx`` file (not a run directory)."""
    return str(policy_id).startswith(NAME_PREFIX) or str(policy_id).endswith(".onnx")


def parse_policy_name(name: str, flag: str = "--policy") -> tuple[str, str]:
    """``holosoma:<robot>/<algo>`` -> ``(robot, algo)``; a ConfigError (naming ``flag``) shows the form and
    the algorithms."""
    match = _NAME.match(name)
    if not match or match.group(2) not in ALGO_FILE_PREFIX:
        raise ConfigError(flag, name, "a shipped policy is named holosoma:<robot>/<algo>",
                          [f"holosoma:{r}/{a}" for r in CARDS for a in ("ppo", "fastsac")])
    return match.group(1), match.group(2)


def model_text(contract: dict[str, Any]) -> str:
    """How the evaluator models the robot, in words, from a contract's dict (:meth:`PolicyContract.to_dict`)."""
    collisions = "self-collisions on" if contract["self_collisions"] else \
        "self-collisions off, colliders touching the floor only"
    return f"robot card {contract['robot']}, as Holosoma's simulator models it: {collisions}"


@dataclass(frozen=True)
class PolicyContract:
    """One imported policy on its robot (see the module docstring): what the ONNX declares, and the
    robot card its joints name. Joint-indexed tuples follow ``dof_names`` (the ONNX's and the card's order).
    """

    policy: str
    onnx_path: str
    input_name: str
    obs_dim: int
    action_dim: int
    dof_names: tuple[str, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    command_ranges: dict[str, list[float]]
    card: RobotCard

    @property
    def physics_dt_s(self) -> float:
        return self.card.physics_dt_s

    @property
    def control_rate_hz(self) -> float:
        return self.card.control_rate_hz

    @property
    def experiment(self) -> str:
        """Holosoma's experiment preset of the robot (its PPO locomotion recipe)."""
        return self.card.holosoma_experiment

    @property
    def inference_preset(self) -> str:
        """holosoma_inference's preset of the robot (the observation convention's source)."""
        return self.card.inference_preset

    def to_dict(self) -> dict[str, Any]:
        """The policy's own fields, the card's name and what the evaluator models from it (for the report)."""
        c = self.card
        return {"policy": self.policy, "onnx_path": self.onnx_path, "input_name": self.input_name,
                "obs_dim": self.obs_dim, "action_dim": self.action_dim, "dof_names": list(self.dof_names),
                "kp": list(self.kp), "kd": list(self.kd), "command_ranges": self.command_ranges, "robot": c.name,
                "experiment": c.holosoma_experiment, "inference_preset": c.inference_preset,
                "physics_dt_s": c.physics_dt_s, "decimation": c.decimation, "self_collisions": c.self_collisions,
                "fall_tilt_rad": c.fall_tilt_rad, "min_base_z_m": c.min_base_z_m}


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


def find_shipped_policy(name: str, fallback_python: str | Path | None = None, flag: str = "--policy") -> Path:
    """:func:`shipped_policy_path` in this interpreter, else in ``fallback_python``'s (``.venv-holosoma``)."""
    try:
        return shipped_policy_path(name, None, flag)
    except ConfigError:
        if fallback_python is None:
            raise
        return shipped_policy_path(name, fallback_python, flag)


def onnx_metadata(path: str | Path) -> dict[str, Any]:
    """The ONNX file's metadata, JSON-decoded where it is JSON; a ConfigError names a file that is not ONNX."""
    model = load_onnx(path, load_external_data=False)
    out: dict[str, Any] = {}
    for prop in model.metadata_props:
        try:
            out[prop.key] = json.loads(prop.value)
        except json.JSONDecodeError:
            out[prop.key] = prop.value
    return out


def robot_card_for(dof_names: Sequence[str], source: str) -> RobotCard:
    """The robot card whose joints are exactly ``dof_names``, in this order; else a ConfigError naming both sides."""
    for c in CARDS.values():
        if tuple(c.dof_names) == tuple(dof_names):
            return c
    for c in CARDS.values():  # same joints, another order: say so
        if sorted(c.dof_names) == sorted(dof_names):
            raise ConfigError(source, "dof_names", f"the joints of robot card '{c.name}' in another order "
                              f"(policy: {list(dof_names)}; card: {list(c.dof_names)})")
    raise ConfigError(source, "dof_names", f"no robot card has the policy's {len(dof_names)} joints "
                      f"{list(dof_names)[:4]}...",
                      [f"{c.name} ({c.num_dofs} joints: {', '.join(c.dof_names[:2])}, ...)" for c in CARDS.values()])


def resolve_contract(policy: str, fallback_python: str | Path | None = None) -> PolicyContract:
    """The :class:`PolicyContract` of a shipped policy name (found by :func:`find_shipped_policy`) or an
    ONNX file (module docstring)."""
    path = find_shipped_policy(policy, fallback_python) if policy.startswith(NAME_PREFIX) else Path(policy)
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
    card = robot_card_for(dof_names, source)
    session = onnx_session(path, source)
    inp, out = session.get_inputs()[0], session.get_outputs()[0]
    contract = PolicyContract(
        policy=policy, onnx_path=str(path.resolve()), input_name=inp.name,
        obs_dim=int(inp.shape[-1]), action_dim=int(out.shape[-1]), dof_names=dof_names,
        kp=tuple(float(v) for v in meta["kp"]), kd=tuple(float(v) for v in meta["kd"]),
        command_ranges={k: list(v) for k, v in (meta.get("command_ranges") or {}).items()}, card=card)
    check_obs_size(contract, source)
    return contract


def check_obs_size(contract: PolicyContract, source: str) -> None:
    """The card's observation width must equal the ONNX input's; else a ConfigError naming both."""
    conv = contract.card.observation
    if conv.obs_dim != contract.obs_dim:
        parts = " + ".join(f"{t} {conv.dims[t]}" for t in conv.terms)
        raise ConfigError(source, f"input '{contract.input_name}'",
                          f"the ONNX policy takes {contract.obs_dim} observations but robot card "
                          f"'{contract.card.name}' builds {conv.obs_dim} ({parts}; history {conv.history_length})")
    if contract.action_dim != len(contract.dof_names):
        raise ConfigError(source, "dof_names", f"the ONNX policy outputs {contract.action_dim} actions for "
                          f"{len(contract.dof_names)} dof_names")


def batched_onnx_policy(contract: PolicyContract) -> Any:
    """The policy as ``f(obs [B, obs_dim] float32) -> actions [B, n]`` for any batch ``B``.

    Holosoma's exporter fixes the batch at 1; the graph is a plain MLP, so the loaded copy's input and
    output take a symbolic batch (the file is not changed). onnxruntime's one-row kernel rounds
    differently from its many-row one: callers that want a row's action not to depend on the batch
    pass at least two rows (:func:`econmotor.locomotion.env.run_episodes` does).
    """
    import onnxruntime as ort

    model = load_onnx(contract.onnx_path, contract.policy)
    for value in [*model.graph.input, *model.graph.output]:
        dims = value.type.tensor_type.shape.dim
        if len(dims) > 0:
            dims[0].dim_param = "batch"
    options = ort.SessionOptions()
    options.intra_op_num_threads = 1
    options.inter_op_num_threads = 1
    session = onnx_session(model.SerializeToString(), contract.onnx_path, options)
    name = contract.input_name

    def act(obs: Any) -> Any:
        return session.run(None, {name: obs.astype("float32", copy=False)})[0]

    return act
