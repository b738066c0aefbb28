"""Shared fixtures of the mjx tests: one jitted env per courier for the whole session.

MJX compiles slowly on a CPU (the hopper's step: ~45 s of CPU), so every test of a courier
shares one batched env (``wrappers.make_env`` on a
:class:`~econmotor.motor_backend.mjx.env.GymCourierEnv`) with jitted ``reset``/``step`` at :data:`NUM_ENVS` envs, and
compiled programs persist across runs in a JAX compilation cache under the system temp dir.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")

import jax
import pytest

jax.config.update("jax_compilation_cache_dir", str(Path(tempfile.gettempdir()) / "econmotor-jax-cache"))
jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)

#: envs per jitted env in these tests (one compile per courier).
NUM_ENVS = 2


class JittedEnv:
    """An env with its jitted reset (``num_envs`` static) and step."""

    def __init__(self, env) -> None:
        self.env = env
        self.reset = jax.jit(env.reset, static_argnums=1)
        self.step = jax.jit(env.step)


_ENVS: dict[str, JittedEnv] = {}


def every_term_objective():
    from econmotor.objectives import EconomicObjectiveSpec

    return EconomicObjectiveSpec(mpl_weight=1.0, energy_weight=0.5, error_weight=0.2, novelty_weight=0.3,
                                 risk_weight=0.4, name="every_term")


def catalog_with_mjx_entry(task_id: str, source: str = "<test>", **changes):
    """A catalog of ``task_id`` alone, its ``backends.mjx`` entry with ``changes`` (from ``source``)."""
    from dataclasses import replace

    from econmotor.tasks.catalog import TaskCatalog, load_catalog

    spec = load_catalog().get(task_id)
    entry = {**spec.backends["mjx"], **changes}
    return TaskCatalog({task_id: replace(spec, backends={**spec.backends, "mjx": entry},
                                         backend_sources={**spec.backend_sources, "mjx": source})})


def jitted_env(task_id: str, physics: str = "mjx", **model_options) -> JittedEnv:
    """The session's env of ``task_id`` (every overlay term weighted), built and jitted once;
    ``physics``: a Gymnasium body's (MJX, whatever the catalog's ``cpu_physics``, or ``"mujoco"``: MuJoCo C
    on the host); ``model_options`` override the catalog entry's."""
    key = (task_id, physics, *sorted(model_options.items()))
    if key not in _ENVS:
        from econmotor.motor_backend.mjx.env import GymCourierEnv
        from econmotor.motor_backend.mjx.wrappers import make_env
        from econmotor.tasks.catalog import load_catalog

        catalog = None
        if model_options:
            shipped = load_catalog().get(task_id).backends["mjx"].get("model_options", {})
            catalog = catalog_with_mjx_entry(task_id, model_options={**shipped, **model_options})
        _ENVS[key] = JittedEnv(make_env(GymCourierEnv, task_id, objective=every_term_objective(), catalog=catalog,
                                        physics=physics))
    return _ENVS[key]


@pytest.fixture(scope="session")
def hopper() -> JittedEnv:
    return jitted_env("hopper_courier")


@pytest.fixture(scope="session")
def hopper_host() -> JittedEnv:
    """The hopper stepped by MuJoCo C on the host (``cpu_physics: mujoco``)."""
    return jitted_env("hopper_courier", physics="mujoco")


@pytest.fixture(scope="session")
def humanoid() -> JittedEnv:
    """The humanoid with its constraint solver run to convergence: the catalog's one Newton
    iteration leaves each step's solve unconverged, and MJX's and MuJoCo C's unconverged steps
    part by percents (a step's reward by up to 2.5%), which would hide the metering compared."""
    return jitted_env("humanoid_courier", iterations=50, ls_iterations=50)
