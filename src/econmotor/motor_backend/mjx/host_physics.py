"""MuJoCo C physics inside the jitted rollout: a thin env's ``frame_skip`` physics steps on the host.

On an accelerator the couriers step in MJX, thousands of envs at once. On a CPU MuJoCo C is faster for the
small Gymnasium bodies (64 hoppers with the meter: 29,500 env steps/s against MJX's 19,800,
``benchmarks/mjx_throughput.py --physics``; the demo's PPO rollout 48 ms against ~100 ms) and needs no XLA
compilation of the physics (the demo's iteration compiles in 3 s instead of 10.6 s). A task's ``cpu_physics: mujoco``
(``tasks/mjx.yaml``, ``mjx/settings.py``) keeps everything else of the mjx backend (the JAX PPO, the
wrappers and their meter, the evaluator, export) and steps the physics in MuJoCo C on a CPU: the env's step
calls :meth:`HostPhysics.step` through ``jax.pure_callback`` (``vmap_method="broadcast_all"``: one call per
batched step, the whole batch at once), so a rollout stays one jitted ``lax.scan`` and only the physics
leaves XLA.

The physics state an episode carries is :class:`HostData`: ``qpos``, ``qvel``, the solver's warm start
``qacc_warmstart`` (MuJoCo C starts each step's constraint solve from it) and the last step's
``qfrc_actuator`` (the meter's mechanical power), float32 as MJX's. The model is the one MJX runs (the
task's ``model_options`` applied, ``mjx/assets.py``); per-episode friction and mass multipliers are applied to
a copy of it before each env's steps, as ``GymCourierEnv.randomized_model`` applies them to MJX's.
A step MuJoCo C rejects (its ``mjWARN_BADQPOS/QVEL/QACC``: a diverged state it resets) returns NaN,
which the Gymnasium bodies' healthy rule reads as a fall, as MJX's NaN would be.

The callback is reentrant: each concurrent call (training, the held-out evaluator beside it) steps its own
model copy and ``MjData`` from a pool; MuJoCo releases the GIL inside ``mj_step``.
"""

from __future__ import annotations

import copy
import functools
import threading
from collections.abc import Mapping
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

__all__ = ["HOST_OBS_PARTS", "RANDOMIZED", "HostData", "HostPhysics"]

#: the observation parts (``robots/gym_couriers.py: OBS_PARTS``) a :class:`HostData` can give
HOST_OBS_PARTS = ("qpos", "qvel", "qvel_clipped", "qfrc_actuator")
#: the episode's randomization draws MuJoCo C applies to its model copy (``GymCourierEnv.randomized_model``'s)
RANDOMIZED = ("friction_scale", "mass_scale")


class HostData(NamedTuple):
    """One env's physics state between control steps (under vmap every field leads with the batch)."""

    qpos: jax.Array
    qvel: jax.Array
    qacc_warmstart: jax.Array
    qfrc_actuator: jax.Array

    def replace(self, **changes: Any) -> HostData:
        """As ``mjx.Data.replace``."""
        return self._replace(**changes)


#: the warnings MuJoCo C gives when it rejects a state (non-finite or huge) and resets the data
_REJECTED = tuple(int(w) for w in (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL,
                                   mujoco.mjtWarning.mjWARN_BADQACC))


def _rejections(d: mujoco.MjData) -> int:
    return sum(d.warning[w].number for w in _REJECTED)


class _Workspace:
    """A model copy and an ``MjData`` per env slot, used by one call at a time."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = copy.copy(model)
        self.datas: list[mujoco.MjData] = []
        self.views: list[tuple[np.ndarray, ...]] = []  # each data's qpos, qvel, warm start, ctrl, qfrc_actuator

    def fit(self, n: int) -> _Workspace:
        while len(self.datas) < n:
            d = mujoco.MjData(self.model)
            self.datas.append(d)
            self.views.append((d.qpos, d.qvel, d.qacc_warmstart, d.ctrl, d.qfrc_actuator))
        return self


class HostPhysics:
    """``frame_skip`` MuJoCo C steps of ``model`` per control step, called from JAX (module docstring)."""

    def __init__(self, model: mujoco.MjModel, frame_skip: int) -> None:
        self.model, self.frame_skip = model, int(frame_skip)
        self._friction = model.geom_friction[:, 0].copy()
        self._mass, self._inertia = model.body_mass.copy(), model.body_inertia.copy()
        self._free: list[_Workspace] = []
        self._lock = threading.Lock()

    def template(self) -> HostData:
        """The state of a fresh ``MjData`` (qpos0, at rest)."""
        m = self.model
        zeros = jnp.zeros((m.nv,), jnp.float32)
        return HostData(jnp.asarray(m.qpos0, jnp.float32), zeros, zeros, zeros)

    def step(self, data: HostData, ctrl: jax.Array, draws: Mapping[str, jax.Array]) -> HostData:
        """``data`` after ``frame_skip`` steps under ``ctrl`` and the episode's randomization ``draws`` (only those
        the env draws cross to the host)."""
        out = (jax.ShapeDtypeStruct(data.qpos.shape, jnp.float32),) + \
            (jax.ShapeDtypeStruct(data.qvel.shape, jnp.float32),) * 3
        keys = tuple(k for k in RANDOMIZED if k in draws)
        args = [data.qpos, data.qvel, data.qacc_warmstart, jnp.asarray(ctrl, jnp.float32), *(draws[k] for k in keys)]
        return HostData(*jax.pure_callback(functools.partial(self._host_step, keys), out, *args,
                                           vmap_method="broadcast_all"))

    def _host_step(self, keys: tuple[str, ...], *arrays: np.ndarray) -> tuple[np.ndarray, ...]:
        """The callback: a free workspace steps the batch (XLA calls it from its own threads, which hold
        no Python state between calls, so workspaces are pooled here, not thread-local)."""
        with self._lock:
            work = self._free.pop() if self._free else _Workspace(self.model)
        try:
            return self._step_batch(work, *arrays[:4], dict(zip(keys, arrays[4:], strict=True)))
        finally:
            with self._lock:
                self._free.append(work)

    def _step_batch(self, work: _Workspace, qpos: np.ndarray, qvel: np.ndarray, warm: np.ndarray,
                    ctrl: np.ndarray, draws: dict[str, np.ndarray]) -> tuple[np.ndarray, ...]:
        m0 = self.model
        lead = qpos.shape[:-1]
        qpos, qvel, warm, ctrl = (np.asarray(a).reshape(-1, a.shape[-1]) for a in (qpos, qvel, warm, ctrl))
        n = qpos.shape[0]
        friction = np.asarray(draws.get("friction_scale", np.ones(n))).reshape(n)
        mass = np.asarray(draws.get("mass_scale", np.ones((n, m0.nbody)))).reshape(n, m0.nbody)
        m = work.fit(n).model
        randomized = bool(draws)
        oq = np.empty((n, m0.nq), np.float32)
        ov, ow, of = (np.empty((n, m0.nv), np.float32) for _ in range(3))
        skip = self.frame_skip
        for i in range(n):
            if randomized:
                m.geom_friction[:, 0] = self._friction * friction[i]
                m.body_mass[:] = self._mass * mass[i]
                m.body_inertia[:] = self._inertia * mass[i][:, None]
            d, (q, v, w, c, f) = work.datas[i], work.views[i]
            q[:], v[:], w[:], c[:] = qpos[i], qvel[i], warm[i], ctrl[i]
            warned = _rejections(d)
            mujoco.mj_step(m, d, nstep=skip)
            if _rejections(d) != warned:  # MuJoCo reset a diverged state: report it as NaN
                oq[i] = ov[i] = ow[i] = of[i] = np.nan
                continue
            oq[i], ov[i], ow[i], of[i] = q, v, w, f
        if randomized:
            m.geom_friction[:, 0], m.body_mass[:], m.body_inertia[:] = self._friction, self._mass, self._inertia
        return tuple(o.reshape(lead + o.shape[1:]) for o in (oq, ov, ow, of))
