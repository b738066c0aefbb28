"""The economic overlay as Holosoma reward terms (runs inside ``.venv-holosoma``).

Each overlay key of a :class:`~econmotor.objectives.CompiledRewardOverlay` becomes one
Holosoma reward term::

    RewardTermCfg(func="econmotor.motor_backend.holosoma.venv.reward_terms:EconOverlayTerm",
                  params={"key": "energy_kwh", ...physical parameters...},
                  weight=gain * scale_k, tags=["econ_overlay"])

so Holosoma's reward manager adds ``raw_k * gain * scale_k * dt`` per env per step, logs
``Episode/rew_econ_<key>`` (weighted) and ``RawEpisode/raw_rew_econ_<key>`` (raw), and PPO /
FastSAC optimise it with the task's own terms. The raw rates come from the simulator
each step (see :func:`econmotor.motor_backend.holosoma.econ_formulas.overlay_term_rates`):

- progress toward the unit of work: base velocity along the commanded direction / metres
  per unit (``progress_mode="velocity"``), or tracked time / seconds per unit (``"time"``,
  whole-body tracking);
- electrical power: sum |torque x joint velocity| / drivetrain efficiency + the windings' heat
  sum k_j torque_j^2 (the robot card's motor model; both averaged over the physics sub-steps of the
  control step) + idle power, the couriers' formula;
- falls: terminations that are not time-outs (``reset_buf & ~time_out_buf``);
- risk: the couriers' tilt risk of the base's tilt (0 within ``tilt_margin_rad``, 1 at ``fall_tilt_rad``);
- novelty: distance of the joint configuration from its running statistics.

Power and risk are the sim-to-sim evaluator's meter (:mod:`econmotor.economics.courier_formulas`) with
the evaluator's constants (``params["meter"]``, the task catalog's: ``locomotion.task.meter_settings``).

All econ terms of one env share one computation per step: the first term the manager
calls (the "leader") computes every rate, the others read them.
"""

from __future__ import annotations

import time
from typing import Any

import torch
from holosoma.managers.observation.terms.locomotion import get_base_lin_vel
from holosoma.managers.reward.base import RewardTermBase

from econmotor.economics import courier_formulas as cf
from econmotor.locomotion.task import meter_constants
from econmotor.motor_backend.holosoma.econ_formulas import (
    OVERLAY_TERM_KEYS,
    base_tilt_rad,
    commanded_progress_m_per_s,
    novelty_step,
    overlay_term_rates,
    torch_namespace,
)

SUPPORTED_KEYS = OVERLAY_TERM_KEYS
TERM_PREFIX = "econ_"
#: seconds spent in econ terms and calls made, in this process (the overhead benchmark reads it).
TIMER = {"seconds": 0.0, "calls": 0}
_STATE_ATTR = "_econmotor_overlay_state"
XP = torch_namespace()


class _OverlayState:
    """Per-environment-batch state shared by all econ terms of one env object."""

    def __init__(self, leader: int, num_envs: int, num_dof: int, device: Any, heat_coeff: Any = ()) -> None:
        self.leader = leader
        self.rates: dict[str, torch.Tensor] = {}
        # the robot card's winding-heat coefficients per joint (W per (N m)^2); none: no motor model
        self.heat_coeff = torch.as_tensor(list(heat_coeff) or [0.0] * num_dof, dtype=torch.float32, device=device)
        self.novelty_mean = torch.zeros(num_envs, num_dof, device=device)
        self.novelty_var = torch.ones(num_envs, num_dof, device=device)
        self.novelty_initialised = False


def _joint_control(env: Any) -> Any:
    for _name, term in env.action_manager.iter_terms():
        if hasattr(term, "torques"):
            return term
    raise RuntimeError("econ overlay: no action term with torques (needs Holosoma's joint_control)")


def _joint_power_w(env: Any, heat_coeff: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(mechanical W, winding heat W) of the control step, averaged over its physics sub-steps."""
    term = _joint_control(env)
    if hasattr(term, "torques_substep") and hasattr(term, "dof_vel_substep"):
        tau = term.torques_substep  # [envs, sub-steps, joints]
        return (cf.mechanical_power_w(tau, term.dof_vel_substep, XP).mean(-1),
                cf.winding_heat_w(tau, heat_coeff, XP).mean(-1))
    return (cf.mechanical_power_w(term.torques, env.simulator.dof_vel, XP),
            cf.winding_heat_w(term.torques, heat_coeff, XP))


def _progress_units_per_s(env: Any, params: dict[str, Any]) -> torch.Tensor:
    if params["progress_mode"] == "time":
        return torch.full((env.num_envs,), 1.0 / params["unit_duration_s"], device=env.device)
    v_xy = get_base_lin_vel(env)[:, :2]
    c_xy = env.command_manager.commands[:, :2]
    return commanded_progress_m_per_s(v_xy, c_xy) / params["meter"]["leg_distance_m"]


def compute_step_rates(env: Any, state: _OverlayState, params: dict[str, Any]) -> dict[str, torch.Tensor]:
    """Every overlay rate for every env at this step (see the module docstring)."""
    fell = (env.reset_buf.bool() & ~env.time_out_buf.bool()).float()
    q = env.simulator.dof_pos
    if not state.novelty_initialised:
        state.novelty_mean[:] = q
        state.novelty_initialised = True
    novelty, state.novelty_mean, state.novelty_var = novelty_step(
        q, state.novelty_mean, state.novelty_var, params["novelty_rate"]
    )
    mechanical_w, heat_w = _joint_power_w(env, state.heat_coeff)
    return overlay_term_rates(
        progress_units_per_s=_progress_units_per_s(env, params),
        mechanical_w=mechanical_w,
        heat_w=heat_w,
        fell=fell,
        tilt_rad=base_tilt_rad(env.simulator.base_quat, XP),
        novelty=novelty,
        constants=meter_constants(params["meter"], float(env.dt)),
        episode_s=float(env.max_episode_length_s),
        xp=XP,
    )


class EconOverlayTerm(RewardTermBase):
    """One overlay key as a stateful Holosoma reward term (raw, unweighted value).

    Params (``RewardTermCfg.params``): ``key`` (one of :data:`SUPPORTED_KEYS`), ``meter`` (the
    courier meter's constants, ``locomotion.task.meter_settings``: ``leg_distance_m`` metres per unit of
    work, ``drivetrain_efficiency``, ``idle_power_w``, ``tilt_margin_rad``, ``fall_tilt_rad``),
    ``unit_duration_s`` (seconds per unit in ``"time"`` mode), ``progress_mode`` (``"velocity"`` |
    ``"time"``), ``novelty_rate``, ``winding_heat_w_per_nm2`` (the robot card's motor model per joint,
    W per (N m)^2; absent: none).
    """

    def __init__(self, cfg: Any, env: Any) -> None:
        super().__init__(cfg, env)
        key = cfg.params.get("key")
        if key not in SUPPORTED_KEYS:
            raise ValueError(f"econ overlay term: unknown key {key!r}; supported: {', '.join(SUPPORTED_KEYS)}")
        self.key = key
        state = getattr(env, _STATE_ATTR, None)
        if state is None:
            state = _OverlayState(id(self), env.num_envs, env.simulator.dof_pos.shape[1], env.device,
                                  cfg.params.get("winding_heat_w_per_nm2") or ())
            setattr(env, _STATE_ATTR, state)
        self.state = state

    def reset(self, env_ids: torch.Tensor | None = None) -> None:
        """Nothing per episode: novelty statistics persist across an env slot's episodes."""

    def __call__(self, env: Any, **params: Any) -> torch.Tensor:
        start = time.perf_counter()
        if self.state.leader == id(self) or not self.state.rates:
            self.state.rates = compute_step_rates(env, self.state, params)
        TIMER["seconds"] += time.perf_counter() - start
        TIMER["calls"] += 1
        return self.state.rates[self.key]
