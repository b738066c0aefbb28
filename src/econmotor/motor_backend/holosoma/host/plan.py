"""Planning a Holosoma run in the main interpreter: presets, simulator, CPU adaptation.

A request ``(task, num_envs, max_steps)`` becomes a :class:`RunPlan`: which Holosoma
experiment preset, which simulator, how many envs and learning iterations, and the
messages that announce every adaptation (the CLI prints them).

``max_steps`` means **environment steps** (one control step of one env, 50 Hz for
G1/T1): PPO runs ``ceil(max_steps / (num_envs * num_steps_per_env))`` iterations, FastSAC
``ceil(max_steps / num_envs)`` global steps. Simulators:

- ``isaacgym`` / ``isaacsim`` / ``mjwarp`` on a CUDA machine: the request runs as asked.
- ``mjwarp`` on the CPU: at most :data:`CPU_WARP_MAX_ENVS` envs, steps capped.
- ``mujoco`` (classic, CPU): exactly 1 env (Holosoma's classic backend is single-env),
  steps capped at ``cpu_max_env_steps`` so a report finishes in minutes.

``simulator="auto"`` picks the first available of isaacgym, isaacsim (CUDA and the
package importable), mjwarp (CUDA), else classic mujoco.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from econmotor.errors import ConfigError

SIMULATORS = ("auto", "isaacgym", "isaacsim", "mjwarp", "mujoco")
ALGOS = ("ppo", "fast_sac")
PPO_STEPS_PER_ENV = 24
CPU_WARP_MAX_ENVS = 64
#: envs when the request leaves num_envs to the backend (0): Holosoma's own G1/T1 presets use 4096 on a GPU.
DEFAULT_GPU_ENVS = 4096
#: default cap on environment steps when training on the CPU (about 2-3 min for PPO on classic MuJoCo).
DEFAULT_CPU_MAX_ENV_STEPS = 9_600

@dataclass(frozen=True)
class Capabilities:
    """What the Holosoma interpreter can use (from the runner's ``probe`` job)."""

    cuda: bool = False
    isaacgym: bool = False
    isaacsim: bool = False
    mujoco_warp: bool = False

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Capabilities:
        return cls(**{k: bool(data.get(k, False)) for k in ("cuda", "isaacgym", "isaacsim", "mujoco_warp")})


@dataclass(frozen=True)
class RunPlan:
    """A request adapted to the machine. ``messages`` announce every change."""

    experiment: str
    algo: str
    simulator: str
    device: str
    num_envs: int
    iterations: int
    env_steps: int
    cpu_sized: bool
    messages: tuple[str, ...] = ()
    requested: dict[str, Any] = field(default_factory=dict)


def choose_simulator(requested: str, caps: Capabilities) -> tuple[str, str]:
    """(simulator, device) for ``requested`` (one of :data:`SIMULATORS`) on a machine with ``caps``."""
    if requested not in SIMULATORS:
        raise ConfigError("<holosoma backend>", "simulator", f"unknown simulator {requested!r}", SIMULATORS)
    device = "cuda:0" if caps.cuda else "cpu"
    if requested == "auto":
        if caps.cuda and caps.isaacgym:
            return "isaacgym", device
        if caps.cuda and caps.isaacsim:
            return "isaacsim", device
        if caps.cuda and caps.mujoco_warp:
            return "mjwarp", device
        return "mujoco", "cpu"
    if requested in ("isaacgym", "isaacsim") and not (caps.cuda and getattr(caps, requested)):
        raise ConfigError("<holosoma backend>", "simulator",
                          f"{requested} needs a CUDA GPU and the {requested} package in .venv-holosoma "
                          f"(cuda={caps.cuda}, {requested}={getattr(caps, requested)})", ("mjwarp", "mujoco"))
    if requested == "mjwarp" and not caps.mujoco_warp:
        raise ConfigError("<holosoma backend>", "simulator", "mujoco_warp is not installed in .venv-holosoma",
                          ("mujoco",))
    return requested, ("cpu" if requested == "mujoco" else device)


def plan_training(
    *,
    experiment: str,
    algo: str,
    simulator: str,
    device: str,
    num_envs: int,
    max_steps: int,
    cpu_max_env_steps: int,
) -> RunPlan:
    """Adapt ``(num_envs, max_steps)`` to the simulator; see the module docstring for the rules."""
    if algo not in ALGOS:
        raise ConfigError("<holosoma backend>", "algo", f"unknown algorithm {algo!r}", ALGOS)
    if num_envs < 0 or max_steps < 1:
        raise ConfigError("<holosoma backend>", "num_envs/max_steps",
                          f"num_envs must be >= 0 (0: the simulator's default) and max_steps >= 1, got "
                          f"{num_envs} and {max_steps}")
    messages: list[str] = []
    on_cpu = device == "cpu"
    if num_envs == 0:  # the simulator's default: no adaptation to announce
        num_envs = 1 if simulator == "mujoco" else (CPU_WARP_MAX_ENVS if on_cpu else DEFAULT_GPU_ENVS)
    envs, steps = num_envs, max_steps
    if simulator == "mujoco" and envs != 1:
        messages.append(f"num_envs {num_envs} -> 1: Holosoma's classic MuJoCo simulator runs exactly one env "
                        "(use simulator mjwarp or isaacgym on a GPU machine for parallel envs)")
        envs = 1
    elif simulator == "mjwarp" and on_cpu and envs > CPU_WARP_MAX_ENVS:
        messages.append(f"num_envs {num_envs} -> {CPU_WARP_MAX_ENVS}: mjwarp on the CPU (no CUDA device)")
        envs = CPU_WARP_MAX_ENVS
    if on_cpu and steps > cpu_max_env_steps:
        messages.append(f"max_steps {max_steps} -> {cpu_max_env_steps} environment steps: CPU training is capped "
                        "(raise cpu_max_env_steps, or run on a GPU machine for the full budget)")
        steps = cpu_max_env_steps
    if on_cpu:
        messages.append(f"CPU-sized {algo} settings: "
                        + ("24 steps/env per iteration, 4 minibatches" if algo == "ppo"
                           else "batch 256, torch.compile and bf16 autocast off"))
    per_iteration = envs * (PPO_STEPS_PER_ENV if algo == "ppo" else 1)
    iterations = max(1, math.ceil(steps / per_iteration))
    return RunPlan(
        experiment=experiment,
        algo=algo,
        simulator=simulator,
        device=device,
        num_envs=envs,
        iterations=iterations,
        env_steps=iterations * per_iteration,
        cpu_sized=on_cpu,
        messages=tuple(messages),
        requested={"num_envs": num_envs, "max_steps": max_steps},
    )
