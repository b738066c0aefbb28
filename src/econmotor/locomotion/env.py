"""N card robots in one process, stepped by MuJoCo C: the walker env that prices (and trains) the G1 and T1.

One :class:`WalkerBatch` holds ``num_slots`` robots of one robot card (:mod:`econmotor.robots`), each
walking the delivery course (:mod:`.course`) under the datapack's stress (:mod:`.stress`), metered by
the couriers' shared formulas (:func:`econmotor.economics.courier_formulas.meter_step`):

- **the model**: the card's (:func:`econmotor.robots.model.model_spec`: the maker's MJCF, the floor,
  the maker's collision filter, the physics step), with the PD law inside MuJoCo's actuators
  (:func:`.model.pd_actuator_spec`: gain ``kp`` on the target, bias ``-kp q - kd qd``, force range the
  effort limits): ``tau = clip(kp (target - q) - kd qd, -limit, limit)`` at every physics step,
  exactly the law Holosoma's simulators apply, computed in C. Each slot has its own model copy,
  so its friction, payload and gains are its episode's draws.
- **a control step** (:meth:`WalkerBatch.observe`, then :meth:`WalkerBatch.act`): pushes due,
  the course's command from the pose, the gait clock and the observation (the card's convention,
  :mod:`econmotor.robots.observation`, over the whole batch at once); then the policy's actions
  (clipped, delayed by the episode's control delay) become PD targets, and each robot's own
  ``MjData`` is stepped ``decimation`` physics steps with ``mj_step`` (the solver's warm start
  carried from step to step, as in a plain ``mj_step`` loop).
- **metering** from what is recorded at each physics step: the base pose (units on the
  forward high-water mark, tilt risk, the fall rule) from the state, joint power from the
  actuator-force sensors (``actuatorfrc``, added to the model) times the joint velocities, and the
  windings' heat from those forces (the card's motor model): the same readings the meter takes
  from ``qfrc_actuator`` and ``qvel``. A fall ends the episode at
  its physics step; nothing after it is metered.
- **seeds**: episode ``i`` draws everything from ``numpy.random.default_rng(seed_i)`` in a fixed
  order and starts from a reset MjData of its slot, and the policy runs on at least two rows
  (onnxruntime's one-row kernel rounds differently): an episode's outcome depends on its seed
  only, not on its slot, batch or process.

The fall rule: the card's (:func:`econmotor.couriers.physics.has_fallen`: tilt past ``fall_tilt_rad``,
the base below ``min_base_z_m``, or the runaway rule: a non-finite state or the base faster than
the card's ``runaway_speed_m_per_s``): a blow-up with the base upright ends the episode as a fall
instead of being scored.

Imports NumPy and MuJoCo only (and onnxruntime for a policy file): worker processes start fast.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mujoco
import numpy as np

from econmotor.couriers.physics import has_fallen, quat_tilt_rad
from econmotor.economics import courier_formulas as cf
from econmotor.economics.termination import TerminationReason
from econmotor.locomotion import course as crs
from econmotor.locomotion.model import FULL_STATE, WalkerModel, set_pd_gains
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings
from econmotor.robots import observation as robot_obs

#: the meter's running sums a walker keeps (no novelty or pose tracking on the course)
_SUMS = ("steps", "units", "best_x", "errors", "energy_wh", "risk_sum")


@dataclass
class Episode:
    """One slot's episode: its seed, its draws and what the course and meter have counted."""

    index: int
    seed: int
    rng: np.random.Generator
    draws: dict[str, float]
    delay: int
    pushes: int = 0
    history: list[np.ndarray] = field(default_factory=list)  # the last ``delay`` actions, oldest first


class WalkerBatch:
    """``num_slots`` robots of one card on the course (module docstring).

    Args:
        walker: the compiled model (:meth:`WalkerModel.build`).
        course: the delivery course; ``command_ranges``: the policy's (caps the speed and yaw rate).
        meter: the meter's constants; ``stress``: the per-episode conditions.
        episode_s: the time limit, s; ``num_slots``: robots stepped together (one after another, in this
            thread: one process per core runs more, :mod:`.evaluation`).
    """

    def __init__(self, walker: WalkerModel, course: crs.CourseSettings, meter: MeterSettings, stress: Stress,
                 episode_s: float, num_slots: int, command_ranges: dict[str, Any] | None = None,
                 runaway_speed_m_per_s: float | None = None) -> None:
        card = walker.card
        self.walker, self.card, self.course, self.meter, self.stress = walker, card, course, meter, stress
        self.n = int(num_slots)
        self.runaway = float(runaway_speed_m_per_s or card.runaway_speed_m_per_s)
        self.control_steps = round(episode_s / card.control_dt_s)
        ranges = dict(command_ranges or card.command_ranges)
        self.vx_max = float(ranges.get("lin_vel_x", (-1.0, 1.0))[1])
        lo, hi = ranges.get("ang_vel_yaw", (-1.0, 1.0))
        self.yaw_range = (float(lo), float(hi))
        self.constants = meter.constants(card.physics_dt_s)
        m = walker.model
        self.models = [copy.copy(m) for _ in range(self.n)]
        self.datas = [mujoco.MjData(m) for _ in range(self.n)]  # each slot steps its own
        decimation = card.decimation
        self._record = (np.zeros((self.n, decimation, walker.nstate)), np.zeros((self.n, decimation, m.nsensordata)))
        self.nq, self.nv = m.nq, m.nv
        self.state = np.zeros((self.n, walker.nstate))
        self.episodes: list[Episode | None] = [None] * self.n
        nd = card.num_dofs
        self.last_action = np.zeros((self.n, nd), dtype=np.float32)
        self.phase = np.tile(robot_obs.initial_phase(np), (self.n, 1))
        self.standing = np.zeros(self.n, dtype=bool)
        self.course_state = crs.course_start(np, (self.n,))
        self.command = np.zeros((self.n, 2))  # (vx, yaw rate) of the current control step
        # per slot: control steps done, the next push's time (s), walking time (s) and distance (m), |y| max
        self.steps = np.zeros(self.n, dtype=np.int64)
        self.start_steps = np.zeros(self.n, dtype=np.int64)  # control steps of the limit used at the start
        self.next_push_s = np.full(self.n, math.inf)
        self.walk_s, self.walk_m, self.max_lateral_m = np.zeros(self.n), np.zeros(self.n), np.zeros(self.n)
        self.delayed = np.zeros(self.n, dtype=bool)
        self.sums = cf.MeterSums(steps=np.zeros(self.n), units=np.zeros(self.n), best_x=np.zeros(self.n),
                                 errors=np.zeros(self.n), energy_wh=np.zeros(self.n), risk_sum=np.zeros(self.n))
        self.heat_wh = np.zeros(self.n)  # the windings' share of energy_wh, per slot
        self._heat_coeff = card.heat_coeff()
        self.default = card.array("default_dof_angles")

    # ------------------------------------------------------------------ episodes
    def start(self, slot: int, index: int, seed: int) -> None:
        """Start episode ``index`` (seeded ``seed``) in ``slot``: its draws, its model, its start state."""
        rng = np.random.default_rng(seed)
        card, st, w, m = self.card, self.stress, self.walker, self.models[slot]
        d = self.datas[slot]
        mujoco.mj_resetData(m, d)
        d.qpos[0:3], d.qpos[3:7] = card.init_pos, (1.0, 0.0, 0.0, 0.0)
        noise = st.initial_joint_noise_rad
        d.qpos[w.qpos_adr] = self.default + (rng.uniform(-noise, noise, card.num_dofs) if noise > 0 else 0.0)
        draws: dict[str, float] = {}
        base = w.model
        m.pair_friction[:] = base.pair_friction
        m.geom_friction[w.floor] = base.geom_friction[w.floor]
        if st.friction_range is not None:
            mu = float(rng.uniform(*st.friction_range))
            m.geom_friction[w.floor, 0] = mu
            m.pair_friction[:, 0:2] = mu
            draws["friction"] = mu
        payload = float(rng.uniform(*st.payload_kg_range)) if st.payload_kg_range is not None else 0.0
        m.body_mass[w.torso] = base.body_mass[w.torso] + payload
        draws["payload_kg"] = payload
        kp_scale = rng.uniform(*st.kp_range, card.num_dofs) if st.kp_range is not None else 1.0
        kd_scale = rng.uniform(*st.kd_range, card.num_dofs) if st.kd_range is not None else 1.0
        set_pd_gains(m, w.actuators, w.kp * kp_scale, w.kd * kd_scale)
        delay = int(rng.integers(st.ctrl_delay_steps[0], st.ctrl_delay_steps[1] + 1)) \
            if st.ctrl_delay_steps is not None else 0
        if delay:
            draws["ctrl_delay_steps"] = float(delay)
        first_push = float(rng.uniform(*st.push_interval_s)) if st.push_interval_s is not None else math.inf
        mujoco.mj_forward(m, d)
        mujoco.mj_getState(m, d, self.state[slot], FULL_STATE)
        self.episodes[slot] = Episode(index, seed, rng, draws, delay,
                                      history=[np.zeros(card.num_dofs, dtype=np.float32)] * delay)
        self.steps[slot], self.next_push_s[slot], self.delayed[slot] = 0, first_push, delay > 0
        self.start_steps[slot] = 0
        self.walk_s[slot] = self.walk_m[slot] = self.max_lateral_m[slot] = 0.0
        self.last_action[slot] = 0.0
        self.phase[slot], self.standing[slot] = robot_obs.initial_phase(np), False
        for part in self.course_state:
            part[slot] = 0.0
        for name in _SUMS:
            getattr(self.sums, name)[slot] = 0.0
        self.heat_wh[slot] = 0.0
        self.sums.best_x[slot] = d.qpos[0]

    def place(self, slot: int, x_m: float, course: crs.CourseState, elapsed_steps: int) -> None:
        """Move the episode just started in ``slot`` to a point of the course: the base translated to ``x_m``
        along the (flat) floor, the course's state ``course`` (leg, dwell left, legs walked) and ``elapsed_steps``
        control steps of the episode's time limit used up (a learner's random start point; the meter counts
        from here: its high-water mark starts at ``x_m``)."""
        self.state[slot, 1] = x_m  # FULL_STATE: time, then qpos (the free root's x first)
        self.load_state(np.array([slot]))
        for part, value in zip(self.course_state, course, strict=True):
            part[slot] = value
        self.steps[slot] = self.start_steps[slot] = int(elapsed_steps)
        self.next_push_s[slot] += elapsed_steps * self.card.control_dt_s
        self.sums.best_x[slot] = x_m

    def load_state(self, slots: np.ndarray) -> None:
        """Make the ``state`` rows of ``slots`` (written by the caller) their robots' physics state."""
        for s in slots:
            mujoco.mj_setState(self.models[s], self.datas[s], self.state[s], FULL_STATE)

    def active(self) -> np.ndarray:
        """The slots running an episode."""
        return np.asarray([e is not None for e in self.episodes])

    # ------------------------------------------------------------------ one control step
    def _qpos(self, state: np.ndarray) -> np.ndarray:
        return state[..., 1:1 + self.nq]

    def _qvel(self, state: np.ndarray) -> np.ndarray:
        return state[..., 1 + self.nq:1 + self.nq + self.nv]

    def observe(self, slots: np.ndarray) -> np.ndarray:
        """Advance ``slots`` to their control step (pushes due, the course's command, the gait clock)
        and return their observations ``[len(slots), obs_dim]`` (float32)."""
        card = self.card
        for s in slots[self.steps[slots] * card.control_dt_s >= self.next_push_s[slots]]:
            self._push(int(s))
        qpos = self._qpos(self.state[slots])
        sub = crs.CourseState(*(p[slots] for p in self.course_state))
        new, vx, yaw_rate = crs.course_command(sub, qpos[:, 0], qpos[:, 1], crs.heading_yaw(qpos[:, 3:7], np),
                                               self.course, card.control_dt_s, self.vx_max, self.yaw_range, np)
        for part, value in zip(self.course_state, new, strict=True):
            part[slots] = value
        self.command[slots, 0], self.command[slots, 1] = vx, yaw_rate
        lin = np.stack([vx, np.zeros_like(vx)], axis=-1)
        phase, standing = robot_obs.advance_phase(self.phase[slots], self.standing[slots], lin, yaw_rate, card, np)
        self.phase[slots], self.standing[slots] = phase, standing
        return self.observation(slots)

    def observation(self, slots: np.ndarray) -> np.ndarray:
        """The observation of ``slots`` at their current state, command and gait clock."""
        w = self.walker
        qpos, qvel = self._qpos(self.state[slots]), self._qvel(self.state[slots])
        lin = np.stack([self.command[slots, 0], np.zeros(len(slots))], axis=-1)
        return robot_obs.build_observation(
            self.card, np, quat_wxyz=qpos[:, 3:7], ang_vel_body=qvel[:, 3:6], q=qpos[:, w.qpos_adr],
            qd=qvel[:, w.dof_adr], lin_vel_cmd=lin, ang_vel_cmd=self.command[slots, 1],
            last_action=self.last_action[slots], phase=self.phase[slots])

    def _push(self, slot: int) -> None:
        """The base velocity kick due in ``slot`` (Holosoma's push randomizer) and the next push's time."""
        ep, st = self.episodes[slot], self.stress
        lo, hi = st.max_push_vel_m_per_s  # type: ignore[misc]
        qvel = self._qvel(self.state[slot])
        qvel[0:2] += ep.rng.uniform(-1.0, 1.0, 2) * np.array([lo, hi])
        self.datas[slot].qvel[0:2] = qvel[0:2]
        self.next_push_s[slot] = self.steps[slot] * self.card.control_dt_s + float(ep.rng.uniform(*st.push_interval_s))
        ep.pushes += 1

    def act(self, slots: np.ndarray, actions: np.ndarray) -> np.ndarray:
        """Step ``slots`` one control step with the policy's ``actions`` ``[len(slots), n]``; returns
        which of them ended (course done, fall, time limit): read them with :meth:`finish`."""
        card, w = self.card, self.walker
        action = np.clip(np.asarray(actions, dtype=np.float32).reshape(len(slots), -1),
                         -card.action_clip, card.action_clip)
        self.last_action[slots] = action
        applied = np.array(action)
        for row in np.flatnonzero(self.delayed[slots]):
            history = self.episodes[slots[row]].history
            history.append(action[row].copy())
            applied[row] = history.pop(0)
        targets = self.default + card.action_scale * applied.astype(np.float64)
        x_before = self._qpos(self.state[slots])[:, 0].copy()
        states, sensors = self._rollout(slots, targets)
        fell = self._meter(slots, states, sensors[:, :, w.frc_adr])
        last = states[:, -1]
        self.state[slots] = last
        walking = self.command[slots, 0] > 0.0  # a walking step's progress counts toward the achieved speed
        qpos = self._qpos(last)
        self.steps[slots] += 1
        self.walk_s[slots] += np.where(walking, card.control_dt_s, 0.0)
        self.walk_m[slots] += np.where(walking, qpos[:, 0] - x_before, 0.0)
        self.max_lateral_m[slots] = np.maximum(self.max_lateral_m[slots], np.abs(qpos[:, 1]))
        finished = crs.course_finished(crs.CourseState(*(p[slots] for p in self.course_state)), self.course, np)
        return fell | finished | (self.steps[slots] >= self.control_steps)

    def _rollout(self, slots: np.ndarray, targets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``decimation`` physics steps of ``slots`` at PD ``targets``: each slot's MjData stepped in turn, its
        qpos, qvel and sensordata recorded after each step (``FULL_STATE``'s layout: time, qpos, qvel, ...)."""
        states, sensors = self._record
        qpos_at, qvel_at, end = 1, 1 + self.nq, 1 + self.nq + self.nv
        step, act = mujoco.mj_step, self.walker.actuators
        for row, s in enumerate(slots):
            m, d = self.models[s], self.datas[s]
            d.ctrl[act] = targets[row]
            state, sensor = states[s], sensors[s]
            for k in range(self.card.decimation):
                step(m, d)
                state[k, qpos_at:qvel_at] = d.qpos
                state[k, qvel_at:end] = d.qvel
                sensor[k] = d.sensordata
        return states[slots], sensors[slots]

    def _meter(self, slots: np.ndarray, states: np.ndarray, frc: np.ndarray) -> np.ndarray:
        """Meter the physics steps ``[B, decimation]`` of ``slots`` up to and including a fall (later steps
        are not metered); returns who fell.

        The same sums as :func:`econmotor.economics.courier_formulas.meter_step` applied at each live
        physics step, taken over the control step at once: the high-water mark over the live steps,
        energy and risk summed over them, one error for a fall.
        """
        w, card, c, s = self.walker, self.card, self.constants, self.sums
        qpos, qvel = self._qpos(states), self._qvel(states)
        tilt = quat_tilt_rad(qpos[..., 4], qpos[..., 5], np)
        fell_at = has_fallen(card, qpos, qvel, np, self.runaway, tilt_rad=tilt)
        # live: the steps up to the first fall (a robot that fell is metered no further)
        live = np.cumsum(np.cumsum(fell_at, axis=1), axis=1) <= 1
        fell = fell_at.any(axis=1)
        x = np.where(live, qpos[..., 0], -np.inf)
        best, units = cf.forward_units(s.best_x[slots], np.nan_to_num(x.max(axis=1), nan=-np.inf), c.leg_distance_m,
                                       np)
        heat_w = cf.winding_heat_w(frc, self._heat_coeff, np)
        energy = cf.electrical_energy_wh(cf.mechanical_power_w(frc, qvel[..., w.dof_adr], np), c.drivetrain_efficiency,
                                         c.idle_power_w, c.dt_s, heat_w)
        risk = cf.tilt_risk(tilt, c.tilt_margin_rad, c.fall_tilt_rad, np)
        s.steps[slots] += live.sum(axis=1)
        s.units[slots] += units
        s.best_x[slots] = best
        s.errors[slots] += fell * 1.0
        s.energy_wh[slots] += np.where(live, energy, 0.0).sum(axis=1)
        s.risk_sum[slots] += np.where(live, risk, 0.0).sum(axis=1)
        self.heat_wh[slots] += np.where(live, heat_w, 0.0).sum(axis=1) * (c.dt_s / cf.SECONDS_PER_HOUR)
        return fell

    # ------------------------------------------------------------------ an episode's figures
    def limit_s(self, slots: Any) -> Any:
        """The time limit of the episodes in ``slots`` from their starts, s (a random start point used some)."""
        return (self.control_steps - self.start_steps[slots]) * self.card.control_dt_s

    def finish(self, slot: int) -> dict[str, Any]:
        """The ended episode of ``slot`` as raw metrics (the standard keys plus the course's); frees the slot."""
        ep, card, s = self.episodes[slot], self.card, self.sums
        n, units, best_x, errors, energy_wh, risk_sum = (float(getattr(s, k)[slot]) for k in _SUMS)
        legs_done = float(self.course_state.legs_done[slot])
        walk_s, walk_m = float(self.walk_s[slot]), float(self.walk_m[slot])
        finished = bool(crs.course_finished(crs.CourseState(*(p[slot] for p in self.course_state)), self.course, np))
        length_s = n * card.physics_dt_s
        power_w = energy_wh * cf.SECONDS_PER_HOUR / length_s if length_s > 0 else 0.0
        heat_w = float(self.heat_wh[slot]) * cf.SECONDS_PER_HOUR / length_s if length_s > 0 else 0.0
        self.episodes[slot] = None
        return {
            "units_completed": units, "units_attempted": units + errors, "errors": errors,
            "episode_length_s": length_s, "length_steps": float(self.steps[slot]), "energy_wh": energy_wh,
            "episode_limit_s": float(self.limit_s(slot)),
            "risk_score": risk_sum / n if n else 0.0, "novelty_score": 0.0,
            "termination_reason": TerminationReason.FALL if errors > 0 else TerminationReason.COURSE_DONE if finished
            else TerminationReason.MAX_STEPS,
            "distance_m": best_x - card.init_pos[0], "legs_reached": legs_done,
            "commanded_speed_m_per_s": min(self.course.speed_m_per_s, self.vx_max),
            "achieved_speed_m_per_s": walk_m / walk_s if walk_s > 0 else 0.0, "walking_s": walk_s,
            "max_lateral_m": float(self.max_lateral_m[slot]), "mean_power_w": power_w, "mean_heat_power_w": heat_w,
            "mean_mech_power_w": cf.mechanical_from_electrical_w(power_w, self.meter.drivetrain_efficiency,
                                                                 self.meter.idle_power_w, heat_w),
            "pushes": float(ep.pushes), **{f"stress_{k}": v for k, v in ep.draws.items()},
        }

    def close(self) -> None:
        """Nothing to release (the batch holds no threads or processes); kept so its callers close any env alike."""


Policy = Callable[[np.ndarray], np.ndarray]


def run_episodes(batch: WalkerBatch, policy: Policy, episodes: list[tuple[int, int]],
                 on_episode: Callable[[int, dict[str, Any]], bool | None] = lambda i, ep: None) -> None:
    """Run ``episodes`` (``(index, seed)`` pairs, started in this order as slots free up) to their ends.

    ``policy(obs [B, obs_dim]) -> actions [B, n]``, one call per control step over every running slot
    (at least two rows: a lone slot's row is padded); ``on_episode(index, metrics)`` as each ends (a
    True return stops starting new episodes).
    """
    run_batches([(batch, episodes)], policy, on_episode)


def run_batches(runs: list[tuple[WalkerBatch, list[tuple[int, int]]]], policy: Policy,
                on_episode: Callable[[int, dict[str, Any]], bool | None] = lambda i, ep: None) -> None:
    """:func:`run_episodes` of several batches (each its own conditions, say) together: a control step of
    every batch in turn, so none waits on another's last episodes; a True ``on_episode`` stops starting
    episodes in all of them. An episode depends on its seed only, so each is the one ``run_episodes`` gives."""
    queues = [list(episodes) for _, episodes in runs]
    for (batch, _), queue in zip(runs, queues, strict=True):
        for slot in range(min(batch.n, len(queue))):
            batch.start(slot, *queue.pop(0))
    stop = False
    while True:
        stepped = False
        for (batch, _), queue in zip(runs, queues, strict=True):
            slots = np.flatnonzero(batch.active())
            if len(slots) == 0:
                continue
            stepped = True
            obs = batch.observe(slots)
            rows = obs if len(slots) > 1 else np.concatenate([obs, obs])
            done = batch.act(slots, np.asarray(policy(rows))[:len(slots)])
            for s in slots[done]:
                stop = bool(on_episode(batch.episodes[s].index, batch.finish(int(s)))) or stop
                if queue and not stop:
                    batch.start(int(s), *queue.pop(0))
        if not stepped:
            return
