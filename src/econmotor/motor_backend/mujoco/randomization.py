"""Domain randomization and curriculum applied to a Gymnasium MuJoCo env (the mujoco backend).

The datapack keys and their validation are the couriers' (``couriers/randomization.py``:
:class:`DomainRandomization`, :class:`Curriculum`, :func:`parse_randomization`); this module
applies them: :class:`DomainRandomizationWrapper` draws friction and masses per episode, pushes
the torso, adds action / observation noise, and :func:`make_base_env` swaps the floor for a
heightfield on rough terrain. Difficulty ``d`` scales every range toward nominal (a multiplier
range ``[lo, hi]`` becomes ``[1 + d (lo - 1), 1 + d (hi - 1)]``; forces, noise stds and terrain
height are multiplied by ``d``).
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from econmotor.couriers.randomization import Curriculum, DomainRandomization, parse_randomization
from econmotor.errors import ConfigError

__all__ = ["Curriculum", "DomainRandomization", "DomainRandomizationWrapper", "make_base_env", "parse_randomization",
           "rough_terrain_xml"]

TERRAIN_HALF_SIZE_M = 30.0
TERRAIN_CELLS = 241
TERRAIN_CLEAR_RADIUS_M = 1.0
_ROUGH_XML: dict[str, str] = {}


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
