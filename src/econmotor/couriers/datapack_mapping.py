"""Datapacks -> Holosoma randomization, curriculum, terrain and motion-file overrides.

``domain_randomization`` keys (each maps onto a term of the preset's
``randomization.setup_terms``; the ``[low, high]`` ranges are validated here):

=========================  ==============================================================
datapack key               Holosoma parameter
=========================  ==============================================================
``terrain``                ``flat``/``plane`` -> ``terrain_locomotion_plane``,
                           ``rough``/``mixed`` -> ``terrain_locomotion_mix``
``friction_range``         ``randomize_friction_startup.friction_range`` (enabled)
``link_mass_range``        ``mass_randomizer.link_mass_range`` (scale factors)
``added_base_mass_kg``     ``mass_randomizer.added_mass_range``
``pushes``                 ``push_randomizer_state.enabled``
``push_interval_s``        ``push_randomizer_state.push_interval_s``
``max_push_vel_m_per_s``   ``push_randomizer_state.max_push_vel`` (x and y)
``kp_range`` / ``kd_range`` ``actuator_randomizer_state.kp_range`` / ``kd_range``
``ctrl_delay_steps``       ``setup_action_delay_buffers.ctrl_delay_step_range``
``initial_joint_noise_rad`` sim-to-sim evaluation only: each joint starts at its default
                           angle plus a uniform draw in ``[-v, v]`` (not a training term)
=========================  ==============================================================

This is the holosoma backend's reading (its training runs and its datapack check; the mujoco backend's
datapack check calls it for the walker tasks' keys too). The walker envs that price and train the card
robots read the same keys themselves, without Holosoma's terms
(:meth:`econmotor.locomotion.stress.Stress.from_datapacks`).

``curriculum`` keys map onto Holosoma's ``PenaltyCurriculum`` (which scales the
penalty-tagged reward terms): ``initial_difficulty`` -> ``initial_scale``,
``min_difficulty`` -> ``min_scale``, ``max_difficulty`` -> ``max_scale``,
``level_up_episode_length`` / ``level_down_episode_length`` -> the thresholds.

Motion clips: the highest-weight clip becomes the whole-body-tracking motion file,
after checking it holds Holosoma's npz keys (:data:`MOTION_NPZ_KEYS`) with consistent shapes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.config.datapacks import DatapackBundle, DatapackConfig
from econmotor.config.loading import as_float, as_range, as_str
from econmotor.errors import ConfigError

MOTION_NPZ_KEYS = ("fps", "joint_pos", "joint_vel", "body_pos_w", "body_quat_w", "body_lin_vel_w",
                   "body_ang_vel_w", "joint_names", "body_names")
TERRAINS = {"flat": "terrain_locomotion_plane", "plane": "terrain_locomotion_plane",
            "rough": "terrain_locomotion_mix", "mixed": "terrain_locomotion_mix"}
#: datapack key -> (randomization setup term, parameter)
_DR_RANGES = {
    "friction_range": ("randomize_friction_startup", "friction_range", 0.0),
    "link_mass_range": ("mass_randomizer", "link_mass_range", 0.0),
    "added_base_mass_kg": ("mass_randomizer", "added_mass_range", None),
    "push_interval_s": ("push_randomizer_state", "push_interval_s", 0.0),
    "kp_range": ("actuator_randomizer_state", "kp_range", 0.0),
    "kd_range": ("actuator_randomizer_state", "kd_range", 0.0),
    "ctrl_delay_steps": ("setup_action_delay_buffers", "ctrl_delay_step_range", 0.0),
}
_ENABLE_FLAGS = {"randomize_friction_startup": "enabled", "setup_action_delay_buffers": "enabled"}
#: keys only the sim-to-sim evaluation uses (HolosomaOverrides.evaluation)
EVALUATION_KEYS = ("initial_joint_noise_rad",)
DR_KEYS = ("terrain", "pushes", "max_push_vel_m_per_s", *_DR_RANGES, *EVALUATION_KEYS)
_CURRICULUM = {"initial_difficulty": "initial_scale", "min_difficulty": "min_scale", "max_difficulty": "max_scale",
               "level_up_episode_length": "level_up_threshold",
               "level_down_episode_length": "level_down_threshold"}
CURRICULUM_KEYS = tuple(_CURRICULUM)


@dataclass(frozen=True)
class HolosomaOverrides:
    """What the runner applies on top of the preset (JSON-ready)."""

    randomization: dict[str, dict[str, Any]] = field(default_factory=dict)  # setup term -> params
    curriculum: dict[str, Any] = field(default_factory=dict)  # PenaltyCurriculum params
    terrain: str | None = None
    motion_file: str | None = None
    motion_duration_s: float | None = None
    messages: tuple[str, ...] = ()
    evaluation: dict[str, Any] = field(default_factory=dict)  # sim-to-sim only (EVALUATION_KEYS)

    def to_dict(self) -> dict[str, Any]:
        return {"randomization": self.randomization, "curriculum": self.curriculum,
                "terrain": self.terrain, "motion_file": self.motion_file, "evaluation": self.evaluation}


def _source_of(bundle: DatapackBundle, packs: Sequence[DatapackConfig], section: str, key: str) -> str:
    """The datapack source that set ``section.key`` last (later packs win), for error messages."""
    for pack in reversed([p for p in packs if p.id in bundle.datapack_ids]):
        if key in getattr(pack, section):
            return pack.source
    return ", ".join(bundle.sources.values()) or "<datapacks>"


def map_datapacks(
    bundle: DatapackBundle, packs: Sequence[DatapackConfig] = (), *, uses_motion_clip: bool
) -> HolosomaOverrides:
    """Validate the bundle's keys for Holosoma and translate them (see the module docstring)."""
    randomization: dict[str, dict[str, Any]] = {}
    messages: list[str] = []
    terrain = None
    evaluation: dict[str, Any] = {}
    for key, value in bundle.domain_randomization.items():
        src, dotted = _source_of(bundle, packs, "domain_randomization", key), f"domain_randomization.{key}"
        if key not in DR_KEYS:
            raise ConfigError(src, dotted, "not supported by the holosoma backend", DR_KEYS)
        if key == "terrain":
            terrain = TERRAINS[as_str(value, src, dotted, TERRAINS)]
        elif key == "pushes":
            if not isinstance(value, bool):
                raise ConfigError(src, dotted, f"expected true or false, got {value!r}")
            randomization.setdefault("push_randomizer_state", {})["enabled"] = value
        elif key in EVALUATION_KEYS:
            evaluation[key] = as_float(value, src, dotted, min_value=0.0)
            messages.append(f"{dotted} applies to the sim-to-sim evaluation only (Holosoma has no such term)")
        elif key == "max_push_vel_m_per_s":
            v = as_float(value, src, dotted, min_value=0.0)
            randomization.setdefault("push_randomizer_state", {})["max_push_vel"] = [v, v]
        else:
            term, param, low = _DR_RANGES[key]
            pair = list(as_range(value, src, dotted, min_value=low))
            if key == "ctrl_delay_steps":
                pair = [round(p) for p in pair]
            randomization.setdefault(term, {})[param] = pair
            if term in _ENABLE_FLAGS:
                randomization[term][_ENABLE_FLAGS[term]] = True
    curriculum: dict[str, Any] = {}
    for key, value in bundle.curriculum.items():
        src, dotted = _source_of(bundle, packs, "curriculum", key), f"curriculum.{key}"
        if key not in _CURRICULUM:
            raise ConfigError(src, dotted, "not supported by the holosoma backend", CURRICULUM_KEYS)
        curriculum[_CURRICULUM[key]] = as_float(value, src, dotted, min_value=0.0)
    motion_file, duration = None, None
    if bundle.motion_clips:
        clip = max(bundle.motion_clips, key=lambda c: c.weight)  # first of equal weights wins
        if uses_motion_clip:
            pack = bundle.clip_origins.get(clip.path, "<datapack>")
            duration = validate_motion_npz(clip.path, bundle.sources.get(pack, pack))["duration_s"]
            motion_file = str(Path(clip.path).resolve())
            if len(bundle.motion_clips) > 1:
                messages.append(f"motion clip {clip.path} (weight {clip.weight}) is the tracking target; "
                                f"{len(bundle.motion_clips) - 1} lower-weight clip(s) unused")
        else:
            messages.append(f"{len(bundle.motion_clips)} motion clip(s) ignored: locomotion presets track "
                            "velocity commands, not clips (use humanoid_wbt_g1)")
    return HolosomaOverrides(randomization, curriculum, terrain, motion_file, duration, tuple(messages), evaluation)


def validate_motion_npz(path: str | Path, source: str) -> dict[str, Any]:
    """Check a Holosoma whole-body-tracking motion file; return its shapes. ConfigError names ``source``."""
    key = "motion_clips.path"
    p = Path(path)
    if not p.is_file():
        raise ConfigError(source, key, f"motion clip {p} not found")
    try:
        with np.load(p, allow_pickle=False) as data:
            missing = [k for k in MOTION_NPZ_KEYS if k not in data.files]
            if missing:
                raise ConfigError(source, key, f"{p} lacks Holosoma motion keys {missing}", MOTION_NPZ_KEYS)
            arrays: Mapping[str, Any] = {k: data[k] for k in MOTION_NPZ_KEYS}
    except (OSError, ValueError) as exc:
        raise ConfigError(source, key, f"{p} is not a readable npz: {exc}") from exc
    frames, joints, bodies = arrays["joint_pos"].shape[0], len(arrays["joint_names"]), len(arrays["body_names"])
    expected = {"joint_pos": (frames, joints + 7), "joint_vel": (frames, joints + 6),
                "body_pos_w": (frames, bodies, 3), "body_quat_w": (frames, bodies, 4),
                "body_lin_vel_w": (frames, bodies, 3), "body_ang_vel_w": (frames, bodies, 3)}
    for name, shape in expected.items():
        if tuple(arrays[name].shape) != shape:
            raise ConfigError(source, key, f"{p}: {name} has shape {tuple(arrays[name].shape)}, expected {shape} "
                              "(joint_pos = root xyz + quat wxyz + joints; joint_vel = root 6 + joints)")
    fps = float(np.asarray(arrays["fps"]).reshape(-1)[0])
    if frames < 2 or not fps > 0:
        raise ConfigError(source, key, f"{p}: needs >= 2 frames and fps > 0, got {frames} frames at {fps} fps")
    return {"frames": frames, "fps": fps, "joints": joints, "bodies": bodies, "duration_s": frames / fps}
