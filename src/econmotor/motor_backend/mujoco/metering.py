"""EconomicMeteringWrapper: read the economics of a MuJoCo rollout from the physics.

Per control step (duration ``dt = frame_skip * timestep`` s), from ``env.unwrapped.data``:

- units: a *delivery leg* is ``leg_distance_m`` of forward (+x) travel of the root.
  Progress is a high-water mark, so moving back and forth earns nothing:
  ``units_t = (max_{s<=t} x_s - x_0) / leg_distance_m`` (fractional legs).
- electrical energy, Wh: mechanical power ``P_mech = sum_j |qfrc_actuator_j * qvel_j|`` W over
  the degrees of freedom (``qfrc_actuator`` is the actuator force *after* the gear; unactuated
  dofs read 0), electrical ``P_el = P_mech / drivetrain_efficiency + idle_power_w``,
  ``energy_wh += P_el * dt / 3600``. Power is sampled at the end of each control step.
- falls: the env's own unhealthy termination (``terminated=True``) is one fall = one error.
- risk in [0, 1]: ``clip((tilt - tilt_margin_rad) / (fall_tilt_rad - tilt_margin_rad), 0, 1)``,
  tilt = the torso's angle from upright (planar robots: the root hinge; free-floating robots:
  from the root quaternion, ``cos(tilt) = 1 - 2 (qx^2 + qy^2)``).
- novelty: ``1 / sqrt(n(s))`` where ``n`` counts visits (kept across episodes of this env) to
  the cell ``floor(obs[:novelty_dims] / novelty_bin)``.

Episode raw metrics (``info["econ_episode"]`` on the last step) use the keys
:class:`~econmotor.economics.EconomicMeter` reads: ``units_completed``, ``units_attempted``
(``= units_completed + errors``: the leg during which the robot fell counts as attempted and
failed), ``errors``, ``episode_length_s``, ``energy_wh``, ``risk_score`` and ``novelty_score``
(means over steps), plus ``return`` (the env's own reward), ``length_steps``,
``forward_distance_m``, ``control_dt_s`` and ``termination_reason`` (``"fall"`` or
``"max_steps"``), and ``pose_tracking`` (sum of per-step pose similarity) when a
pose-tracking wrapper reports ``info["pose_tracking"]``.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import mujoco

from econmotor.errors import ConfigError


class EpisodeTally:
    """Running sums of one episode; the overlay reads the running episode metrics from here."""

    __slots__ = (
        "dt_s",
        "energy_wh",
        "errors",
        "novelty_sum",
        "pose_sum",
        "risk_sum",
        "steps",
        "task_return",
        "units",
    )

    def __init__(self, dt_s: float) -> None:
        self.dt_s = dt_s
        self.reset()

    def reset(self) -> None:
        self.steps = 0
        self.units = self.errors = self.energy_wh = 0.0
        self.risk_sum = self.novelty_sum = self.pose_sum = self.task_return = 0.0

    # running episode metrics (the values the episode would report if it ended now)
    def mpl_per_hour(self) -> float:
        """Good units per hour so far: ``units / (steps * dt / 3600)``."""
        return self.units * 3600.0 / (self.steps * self.dt_s) if self.steps else 0.0

    def error_rate(self) -> float:
        """Errors per attempted unit so far: ``errors / (units + errors)``."""
        attempted = self.units + self.errors
        return self.errors / attempted if attempted > 0 else 0.0

    def energy_kwh(self) -> float:
        return self.energy_wh / 1000.0

    def risk_score(self) -> float:
        return self.risk_sum / self.steps if self.steps else 0.0

    def novelty_score(self) -> float:
        return self.novelty_sum / self.steps if self.steps else 0.0

    def pose_tracking(self) -> float:
        return self.pose_sum

    def running_metrics(self) -> tuple[float, float, float, float, float, float]:
        """All six running metrics at once, in :data:`RUNNING_METRIC_KEYS` order (one call per step)."""
        steps, units, errors = self.steps, self.units, self.errors
        attempted = units + errors
        if steps:
            return (units * 3600.0 / (steps * self.dt_s), errors / attempted if attempted > 0 else 0.0,
                    self.energy_wh / 1000.0, self.risk_sum / steps, self.novelty_sum / steps, self.pose_sum)
        return (0.0, 0.0, self.energy_wh / 1000.0, 0.0, 0.0, self.pose_sum)


#: overlay keys in the order of :meth:`EpisodeTally.running_metrics`.
RUNNING_METRIC_KEYS = ("mpl_per_hour", "error_rate", "energy_kwh", "risk_score", "novelty_score", "pose_tracking")


class EconomicMeteringWrapper(gym.Wrapper):
    """Meter units, energy, falls, risk and novelty of a Gymnasium MuJoCo env (see module doc).

    Args:
        env: a Gymnasium MuJoCo env (``env.unwrapped`` has ``model``, ``data`` and ``dt``);
            wrap it *outside* ``TimeLimit`` so truncations are seen.
        leg_distance_m: forward distance of one unit of work, m (> 0).
        drivetrain_efficiency: electrical-to-mechanical efficiency in (0, 1].
        idle_power_w: electrical power drawn while on, W (>= 0).
        tilt_margin_rad: tilt with zero risk, rad.
        fall_tilt_rad: tilt at which risk reaches 1, rad (> tilt_margin_rad).
        novelty_dims: leading observation dims hashed for visit counts (>= 1).
        novelty_bin: bin width of the hash, in observation units (> 0).
    """

    def __init__(self, env: gym.Env, leg_distance_m: float = 10.0, drivetrain_efficiency: float = 0.6,
                 idle_power_w: float = 20.0, tilt_margin_rad: float = 0.2, fall_tilt_rad: float = 1.0,
                 novelty_dims: int = 5, novelty_bin: float = 0.25) -> None:
        super().__init__(env)
        where = "EconomicMeteringWrapper"
        if not leg_distance_m > 0:
            raise ConfigError(where, "leg_distance_m", f"must be > 0, got {leg_distance_m}")
        if not 0 < drivetrain_efficiency <= 1:
            raise ConfigError(where, "drivetrain_efficiency", f"must be in (0, 1], got {drivetrain_efficiency}")
        if idle_power_w < 0:
            raise ConfigError(where, "idle_power_w", f"must be >= 0, got {idle_power_w}")
        if not fall_tilt_rad > tilt_margin_rad >= 0:
            raise ConfigError(where, "fall_tilt_rad", "need fall_tilt_rad > tilt_margin_rad >= 0")
        if novelty_dims < 1 or not novelty_bin > 0:
            raise ConfigError(where, "novelty_bin", "need novelty_dims >= 1 and novelty_bin > 0")
        base = env.unwrapped
        if not hasattr(base, "data") or not hasattr(base, "model"):
            raise ConfigError(where, "env", f"{base!r} is not a MuJoCo env (no model/data)")
        self._data = base.data
        # views into MjData's fixed buffers, read every step
        self._qfrc, self._qvel = base.data.qfrc_actuator, base.data.qvel
        self.dt_s = float(base.dt)
        self.leg_distance_m = float(leg_distance_m)
        self._inv_eff = 1.0 / float(drivetrain_efficiency)
        self._idle_w = float(idle_power_w)
        self._tilt_margin = float(tilt_margin_rad)
        self._tilt_span = float(fall_tilt_rad - tilt_margin_rad)
        self._novelty_dims = int(novelty_dims)
        self._inv_bin = 1.0 / float(novelty_bin)
        self._free_root = int(base.model.jnt_type[0]) == int(mujoco.mjtJoint.mjJNT_FREE)
        self._wh_per_w = self.dt_s / 3600.0
        self.visit_counts: dict[tuple[int, ...], int] = {}  # cell -> visits
        self.tally = EpisodeTally(self.dt_s)
        self._x0 = self._best_x = 0.0

    def tilt_rad(self) -> float:
        """The torso's angle from upright, rad."""
        qpos = self._data.qpos
        if self._free_root:
            c = 1.0 - 2.0 * (qpos[4] * qpos[4] + qpos[5] * qpos[5])
            return math.acos(max(-1.0, min(1.0, c)))
        return abs(float(qpos[2]))

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self.tally.reset()
        self._x0 = self._best_x = float(self._data.qpos[0])
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        data, tally = self._data, self.tally
        tally.steps += 1
        tally.task_return += float(reward)
        x = float(data.qpos[0])
        if x > self._best_x:
            tally.units += (x - self._best_x) / self.leg_distance_m
            self._best_x = x
        mech_w = sum(map(abs, (self._qfrc * self._qvel).tolist()))  # faster than np.abs(...).sum() here
        tally.energy_wh += (mech_w * self._inv_eff + self._idle_w) * self._wh_per_w
        if terminated:
            tally.errors += 1.0
        excess = (self.tilt_rad() if self._free_root else abs(float(data.qpos[2]))) - self._tilt_margin
        if excess > 0:
            tally.risk_sum += min(1.0, excess / self._tilt_span)
        inv = self._inv_bin
        key = tuple([math.floor(v * inv) for v in obs[: self._novelty_dims].tolist()])
        count = self.visit_counts.get(key, 0) + 1
        self.visit_counts[key] = count
        tally.novelty_sum += count ** -0.5
        pose = info.get("pose_tracking")
        if pose is not None:
            tally.pose_sum += pose
        if terminated or truncated:
            info["econ_episode"] = self.episode_raw_metrics(terminated, pose is not None)
        return obs, reward, terminated, truncated, info

    def episode_raw_metrics(self, fell: bool, with_pose: bool = False) -> dict[str, Any]:
        """The episode's raw metrics so far (keys in the module docstring)."""
        t = self.tally
        out: dict[str, Any] = {
            "units_completed": t.units,
            "units_attempted": t.units + t.errors,
            "errors": t.errors,
            "episode_length_s": t.steps * self.dt_s,
            "length_steps": float(t.steps),
            "control_dt_s": self.dt_s,
            "energy_wh": t.energy_wh,
            "risk_score": t.risk_score(),
            "novelty_score": t.novelty_score(),
            "return": t.task_return,
            "forward_distance_m": self._best_x - self._x0,
            "termination_reason": "fall" if fell else "max_steps",
        }
        if with_pose:
            out["pose_tracking"] = t.pose_sum
        return out


def find_wrapper(env: gym.Env, cls: type) -> Any:
    """The first wrapper of type ``cls`` in ``env``'s wrapper chain, or None."""
    while env is not None:
        if isinstance(env, cls):
            return env
        env = getattr(env, "env", None)
    return None
