"""Domain randomization and curriculum for the mujoco backend (datapack keys, validated here).

``domain_randomization`` keys (all optional)::

    friction_range: [0.5, 1.0]     # multipliers of every geom's nominal sliding friction, one draw per episode
    mass_scale_range: [0.8, 1.2]   # multipliers of each body's nominal mass (and inertia), drawn per body
    push_interval_s: 2.0           # a horizontal push on the torso every this many seconds ...
    push_force_n: 50.0             # ... of this force, N, for one control step, random direction
    action_noise_std: 0.05         # Gaussian noise added to actions (then clipped to the action space)
    obs_noise_std: 0.01            # Gaussian noise added to observations
    terrain: flat | rough          # rough = a heightfield of random bumps ...
    terrain_max_height_m: 0.05     # ... up to this height at difficulty 1

``curriculum`` keys::

    initial_difficulty: 0.1        # difficulty d at step 0
    max_difficulty: 1.0            # ... reached after ramp_steps
    ramp_steps: 100000             # linear ramp over training environment steps

Difficulty ``d`` scales every range toward nominal: a multiplier range ``[lo, hi]``
becomes ``[1 + d (lo - 1), 1 + d (hi - 1)]``; forces, noise stds and terrain height
are multiplied by ``d``. Without a curriculum ``d = 1`` (the ranges as written).
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from econmotor.config.loading import as_float, as_int, as_range, as_str, check_keys
from econmotor.errors import ConfigError

DR_KEYS = ("friction_range", "mass_scale_range", "push_interval_s", "push_force_n", "action_noise_std",
           "obs_noise_std", "terrain", "terrain_max_height_m")
CURRICULUM_KEYS = ("initial_difficulty", "max_difficulty", "ramp_steps")
TERRAIN_HALF_SIZE_M = 30.0
TERRAIN_CELLS = 241
TERRAIN_CLEAR_RADIUS_M = 1.0
_ROUGH_XML: dict[str, str] = {}


@dataclass(frozen=True)
class DomainRandomization:
    """Validated ``domain_randomization`` settings (see module docstring)."""

    friction_range: tuple[float, float] | None = None
    mass_scale_range: tuple[float, float] | None = None
    push_interval_s: float = 0.0
    push_force_n: float = 0.0
    action_noise_std: float = 0.0
    obs_noise_std: float = 0.0
    terrain: str = "flat"
    terrain_max_height_m: float = 0.05

    @property
    def active(self) -> bool:
        return self != DomainRandomization()


@dataclass(frozen=True)
class Curriculum:
    """Validated ``curriculum``: ``d(step) = d0 + (d1 - d0) * min(1, step / ramp_steps)``."""

    initial_difficulty: float = 1.0
    max_difficulty: float = 1.0
    ramp_steps: int = 0

    def difficulty(self, step: int) -> float:
        if self.ramp_steps <= 0:
            return self.max_difficulty
        frac = min(1.0, max(0.0, step / self.ramp_steps))
        return self.initial_difficulty + (self.max_difficulty - self.initial_difficulty) * frac


def parse_randomization(dr: Mapping[str, Any], cur: Mapping[str, Any],
                        source: str = "<datapacks>") -> tuple[DomainRandomization, Curriculum]:
    """Validate merged datapack ``domain_randomization`` / ``curriculum`` blocks.

    ``source`` names the datapack(s) the keys came from; unknown keys, bad ranges and
    wrong types raise a ConfigError naming it, the key and the supported keys.
    """
    check_keys(dr, DR_KEYS, source, "domain_randomization")
    check_keys(cur, CURRICULUM_KEYS, source, "curriculum")
    kw: dict[str, Any] = {}
    for key in ("friction_range", "mass_scale_range"):
        if key in dr:
            low, high = as_range(dr[key], source, f"domain_randomization.{key}", min_value=0.0)
            if high <= 0:
                raise ConfigError(source, f"domain_randomization.{key}", "multipliers must be > 0")
            kw[key] = (low, high)
    for key in ("push_interval_s", "push_force_n", "action_noise_std", "obs_noise_std", "terrain_max_height_m"):
        if key in dr:
            kw[key] = as_float(dr[key], source, f"domain_randomization.{key}", allow_negative=False)
    if "terrain" in dr:
        kw["terrain"] = as_str(dr["terrain"], source, "domain_randomization.terrain", ("flat", "rough"))
    if kw.get("push_force_n", 0) > 0 and kw.get("push_interval_s", 0) <= 0:
        raise ConfigError(source, "domain_randomization.push_interval_s", "must be > 0 when push_force_n is set")
    ckw: dict[str, Any] = {}
    for key in ("initial_difficulty", "max_difficulty"):
        if key in cur:
            ckw[key] = as_float(cur[key], source, f"curriculum.{key}", min_value=0.0, max_value=1.0)
    if "ramp_steps" in cur:
        ckw["ramp_steps"] = as_int(cur["ramp_steps"], source, "curriculum.ramp_steps", min_value=0)
    if ckw and "initial_difficulty" in ckw and "ramp_steps" not in ckw:
        ckw["ramp_steps"] = 100_000
    curriculum = Curriculum(**ckw)
    if curriculum.initial_difficulty > curriculum.max_difficulty:
        raise ConfigError(source, "curriculum.initial_difficulty", "must not exceed max_difficulty")
    return DomainRandomization(**kw), curriculum


def _scaled_range(rng: tuple[float, float], d: float) -> tuple[float, float]:
    return 1.0 + d * (rng[0] - 1.0), 1.0 + d * (rng[1] - 1.0)


def rough_terrain_xml(base_xml: str | Path, out_dir: str | Path) -> Path:
    """Write a copy of ``base_xml`` whose floor plane is a heightfield named ``terrain``."""
    tree = ET.parse(base_xml)
    root = tree.getroot()
    floors = [g for g in root.iter("geom") if g.get("type") == "plane"]
    if not floors:
        raise ConfigError(str(base_xml), "domain_randomization.terrain", "model has no floor plane to make rough")
    floor = floors[0]
    floor.set("type", "hfield")
    floor.set("hfield", "terrain")
    floor.attrib.pop("size", None)
    floor.attrib.pop("material", None)
    asset = root.find("asset")
    if asset is None:
        asset = ET.SubElement(root, "asset")
    ET.SubElement(asset, "hfield", name="terrain", nrow=str(TERRAIN_CELLS), ncol=str(TERRAIN_CELLS),
                  size=f"{TERRAIN_HALF_SIZE_M} {TERRAIN_HALF_SIZE_M} 1.0 0.1")
    out = Path(out_dir) / f"rough_{Path(base_xml).name}"
    tree.write(out)
    return out


def make_base_env(env_id: str, env_kwargs: Mapping[str, Any], randomization: DomainRandomization) -> gym.Env:
    """``gymnasium.make(env_id, **env_kwargs)``, with a heightfield floor when terrain is rough."""
    kwargs = dict(env_kwargs)
    if randomization.terrain == "rough":
        probe = gym.make(env_id, **kwargs)
        base_xml = probe.unwrapped.fullpath
        probe.close()
        if base_xml not in _ROUGH_XML:  # one model file per process and base model
            _ROUGH_XML[base_xml] = str(rough_terrain_xml(base_xml, tempfile.mkdtemp(prefix="econmotor_terrain_")))
        kwargs["xml_file"] = _ROUGH_XML[base_xml]
    return gym.make(env_id, **kwargs)


class DomainRandomizationWrapper(gym.Wrapper):
    """Apply :class:`DomainRandomization` scaled by a difficulty ``d`` in [0, 1].

    Friction, masses and terrain are drawn at each reset (read them back from
    ``env.unwrapped.model``); pushes, action and observation noise act every step.
    ``set_difficulty(d)`` (called by the training curriculum) takes effect at the next reset
    for the physical parameters and at once for noise and pushes.
    """

    def __init__(self, env: gym.Env, randomization: DomainRandomization, difficulty: float = 1.0,
                 seed: int | None = None) -> None:
        super().__init__(env)
        self.randomization = randomization
        self.difficulty = float(difficulty)
        self._rng = np.random.default_rng(seed)
        model = env.unwrapped.model
        self._model, self._data = model, env.unwrapped.data
        self._friction0 = model.geom_friction[:, 0].copy()
        self._mass0 = model.body_mass.copy()
        self._inertia0 = model.body_inertia.copy()
        self._dt = float(env.unwrapped.dt)
        self._push_every = max(1, round(randomization.push_interval_s / self._dt)) \
            if randomization.push_interval_s > 0 else 0
        self._steps = 0
        self._has_hfield = model.nhfield > 0 and randomization.terrain == "rough"
        if randomization.terrain == "rough" and model.nhfield == 0:
            raise ConfigError("domain_randomization", "terrain", "rough terrain needs the env built by make_base_env")

    def set_difficulty(self, difficulty: float) -> None:
        self.difficulty = float(min(1.0, max(0.0, difficulty)))

    def _apply_physics(self) -> None:
        r, d, model = self.randomization, self.difficulty, self._model
        if r.friction_range is not None:
            model.geom_friction[:, 0] = self._friction0 * self._rng.uniform(*_scaled_range(r.friction_range, d))
        if r.mass_scale_range is not None:
            scale = self._rng.uniform(*_scaled_range(r.mass_scale_range, d), size=model.nbody)
            scale[0] = 1.0  # the world body
            model.body_mass[:] = self._mass0 * scale
            model.body_inertia[:] = self._inertia0 * scale[:, None]
        if self._has_hfield:
            n = int(model.hfield_nrow[0])
            coarse = self._rng.uniform(0.0, 1.0, size=(n // 8 + 2, n // 8 + 2))
            heights = np.kron(coarse, np.ones((8, 8)))[:n, :n]
            axis = np.linspace(-TERRAIN_HALF_SIZE_M, TERRAIN_HALF_SIZE_M, n)
            near = np.hypot(*np.meshgrid(axis, axis)) < TERRAIN_CLEAR_RADIUS_M
            heights[near] = 0.0
            model.hfield_data[:] = (heights * r.terrain_max_height_m * d / model.hfield_size[0, 2]).ravel()

    def reset(self, **kwargs: Any):
        if "seed" in kwargs and kwargs["seed"] is not None:
            self._rng = np.random.default_rng(kwargs["seed"] + 7919)
        self._apply_physics()
        self._steps = 0
        obs, info = self.env.reset(**kwargs)
        return self._noisy_obs(obs), info

    def _noisy_obs(self, obs: np.ndarray) -> np.ndarray:
        std = self.randomization.obs_noise_std * self.difficulty
        return obs + self._rng.normal(0.0, std, size=obs.shape) if std > 0 else obs

    def step(self, action):
        r, d = self.randomization, self.difficulty
        if r.action_noise_std > 0 and d > 0:
            space = self.action_space
            action = np.clip(action + self._rng.normal(0.0, r.action_noise_std * d, size=np.shape(action)),
                             space.low, space.high)
        self._steps += 1
        pushing = self._push_every and self._steps % self._push_every == 0 and r.push_force_n * d > 0
        if pushing:
            angle = self._rng.uniform(0.0, 2 * np.pi)
            self._data.xfrc_applied[1, :2] = r.push_force_n * d * np.array([np.cos(angle), np.sin(angle)])
        obs, reward, terminated, truncated, info = self.env.step(action)
        if pushing:
            self._data.xfrc_applied[1, :2] = 0.0
        return self._noisy_obs(obs), reward, terminated, truncated, info
