"""The batched walker env as a learner sees it: random start points, the step reward and a critic's view.

:class:`WalkerLearningEnv` drives a :class:`~econmotor.locomotion.env.WalkerBatch` (the env that
prices the G1 and T1: the same model, course, stress, meter and fall rule) for a trainer:

- **episodes start at random points of the course** (Holosoma's random episode start times): a leg
  ``k`` of the course's legs, then either part-way along it or in its dwell, the base placed
  there and the time the course would have taken so far counted against the episode's limit
  (:func:`start_point`); an episode then runs to the course's end, a fall or the time limit, so
  the learner practises standing starts, dwells and every leg the priced course has;
- **the step reward** ``r = sum_k w_k term_k dt + gain * (J_T(t) - J_T(t - 1))``: Holosoma's locomotion terms
  (all of :data:`econmotor.locomotion.rewards.TERMS`, on the reading the MJX env takes,
  :meth:`WalkerLearningEnv.reading`) plus ``gain`` times the increment of the objective's J, the very J
  selection and the report score an episode by (:func:`econmotor.objectives.loader.running_objective_j` on the
  meter's running sums, from ``J = 0`` at the episode's start). While the episode runs its rates are taken
  over ``T``, the episode's nominal length (:func:`nominal_length_s`: the course left from the start point at
  the course's speed, dwells included, within the time limit; under ``pace="walker"`` at the walker's own
  walking speed instead, an average of this env's finished episodes', so ``T`` is about the length its
  episodes take), so each leg walked is paid ``3600 w_mpl / T`` when it is walked and each Wh when it is
  drawn; the step that ends the episode adds the difference between its J over its own length and over
  ``T``. An episode's economic rewards sum to ``gain * J`` of that episode,
  with its own length and legs. (Paying the increments of the running rate ``3600 legs / t`` instead credits a
  leg walked at ``t`` with about ``3600 H / t^2`` within the discount's horizon ``H``: far too much in an
  episode's first seconds and almost nothing later, and a fall, which keeps the rate, would cost next to
  nothing);
- **terminated** only by a fall (the card's rule, the runaway rule included); the course's end and the
  time limit **truncate** (the trainer bootstraps them with the critic);
- **a privileged view** for the critic (:meth:`WalkerLearningEnv.privileged`): the base's velocity
  in its own frame and height, the episode's friction and payload, the dwell left and the share of
  the time limit left, things a deployed actor cannot observe.

NumPy and MuJoCo only (no learner): the mujoco backend's trainer (torch) runs it; another trainer may.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from econmotor.economics import courier_formulas as cf
from econmotor.locomotion import course as crs
from econmotor.locomotion import rewards as lr
from econmotor.locomotion.env import WalkerBatch
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.objectives.loader import running_objective_j
from econmotor.robots.observation import projected_gravity, rotate_inverse

#: width of :meth:`WalkerLearningEnv.privileged`
PRIVILEGED_DIM = 9
#: the walking speeds ``T`` may be taken at: the course's commanded one, or the walker's own (module docstring)
PACES = ("course", "walker")
#: a finished episode's weight in the walker's pace (an exponential average over its last ten or so)
PACE_WEIGHT = 0.1


def course_point(course: crs.CourseSettings, u: Any, control_dt_s: float, limit_steps: int,
                 xp: Any) -> tuple[Any, crs.CourseState, Any]:
    """The point of the course that three uniforms ``u[..., 0:3]`` in [0, 1) pick: ``(x_m, course state,
    elapsed control steps)`` (pure; NumPy or JAX).

    A leg ``k`` uniform over the course's legs (1 for an endless course); then, with the dwell's share
    of a leg's nominal time (walking at the course speed), in the dwell at the leg's end with a uniform
    time left, else a uniform fraction along the leg. The elapsed time is the nominal time to get there,
    capped a second short of the time limit.
    """
    legs = max(int(course.legs), 1)
    k = xp.floor(u[..., 0] * legs)
    walk_s = course.leg_m / max(course.speed_m_per_s, 1e-6)
    dwell_share = course.dwell_s / (walk_s + course.dwell_s) if course.dwell_s > 0 else 0.0
    in_dwell = u[..., 1] < dwell_share
    left = u[..., 2] * course.dwell_s
    x = xp.where(in_dwell, (k + 1.0) * course.leg_m, (k + u[..., 2]) * course.leg_m)
    state = crs.CourseState(k, xp.where(in_dwell, left, 0.0), xp.where(in_dwell, k + 1.0, k))
    elapsed_s = k * (walk_s + course.dwell_s) + xp.where(in_dwell, walk_s + course.dwell_s - left,
                                                          u[..., 2] * walk_s)
    steps = xp.minimum(xp.floor(elapsed_s / control_dt_s), limit_steps - 1.0 / control_dt_s)
    return x, state, steps


def nominal_length_s(course: crs.CourseSettings, time_left_s: float, x_m: float = 0.0, legs_done: float = 0.0,
                     dwell_left_s: float = 0.0, speed_m_per_s: float | None = None) -> float:
    """The seconds the course left from a point (the base ``x_m`` along it, ``legs_done`` legs walked,
    ``dwell_left_s`` of a dwell still to stand) takes walking at ``speed_m_per_s`` (None: the course's) with
    every dwell stood, within the episode's ``time_left_s`` (an endless course's: that time); at least a
    millisecond."""
    if course.legs <= 0:
        return max(time_left_s, 1e-3)
    speed = max(speed_m_per_s if speed_m_per_s is not None else course.speed_m_per_s, 1e-6)
    left_s = max(course.legs * course.leg_m - x_m, 0.0) / speed + (course.legs - legs_done) * course.dwell_s \
        + dwell_left_s
    return max(min(left_s, time_left_s), 1e-3)


def start_point(course: crs.CourseSettings, rng: np.random.Generator, control_dt_s: float,
                limit_steps: int) -> tuple[float, crs.CourseState, int]:
    """A random point of the course (:func:`course_point` of three uniforms drawn from ``rng``)."""
    x, state, steps = course_point(course, rng.uniform(size=3), control_dt_s, limit_steps, np)
    return float(x), crs.CourseState(*(float(v) for v in state)), int(steps)


@dataclass
class StepOut:
    """One control step of every robot: the next observations and what the learner needs."""

    obs: np.ndarray  # [N, obs_dim]: after resets, the new episodes' first observations
    privileged: np.ndarray  # [N, PRIVILEGED_DIM]
    reward: np.ndarray  # [N]
    terminated: np.ndarray  # [N] a fall
    truncated: np.ndarray  # [N] the course's end or the time limit
    terminal_obs: np.ndarray  # [N, obs_dim]: the ended episodes' last observations (rows of the others: 0)
    terminal_privileged: np.ndarray
    episodes: list[dict[str, Any]] = field(default_factory=list)  # the ended episodes' raw metrics
    terms: dict[str, float] = field(default_factory=dict)  # the step's mean reward per part


class WalkerLearningEnv:
    """``batch.n`` robots on the course for a learner (module docstring).

    Args:
        batch: the walker env (its course, meter and stress are the priced ones).
        objective / economics: the objective whose J the learner is paid in, and the task's economics (its
            electricity price, for an objective that prices energy).
        gain: J's weight against the locomotion terms (reward units per unit of J).
        weights / params: locomotion term weights and parameters (keys of :data:`econmotor.locomotion.rewards.TERMS`).
        seed: episode ``i`` started by this env is seeded ``seed + i * seed_stride`` (a stride of ``W``: one of
            ``W`` envs that share a run's seed range, each started ``w`` apart).
        random_start: start episodes at random points of the course (else at its start).
    """

    def __init__(self, batch: WalkerBatch, objective: EconomicObjectiveSpec, economics: Any, gain: float,
                 weights: Mapping[str, float], params: Mapping[str, Mapping[str, Any]] | None = None, seed: int = 0,
                 random_start: bool = True, seed_stride: int = 1, pace: str = "course") -> None:
        if pace not in PACES:
            raise ValueError(f"pace must be one of {list(PACES)}, got {pace!r}")
        unknown = sorted(set(weights) - set(lr.TERMS))
        if unknown:
            raise ValueError(f"unknown locomotion terms {unknown}; the walker trainer has {list(lr.TERMS)}")
        self.batch, self.objective, self.economics, self.gain = batch, objective, economics, float(gain)
        self._j = np.zeros(batch.n)  # each slot's episode J so far, over its nominal length
        self._limit_s = batch.control_steps * batch.card.control_dt_s
        #: the walking speed ``T`` is taken at (module docstring): the course's, or under ``pace: walker`` an
        #: average of this env's finished episodes' own
        self.pace, self.pace_m_per_s = pace, float(batch.course.speed_m_per_s)
        self._length_s = np.full(batch.n, nominal_length_s(batch.course, self._limit_s))
        self.weights, self.params = dict(weights), {k: dict(v) for k, v in (params or {}).items()}
        self.next_seed, self.random_start, self.seed_stride = int(seed), bool(random_start), int(seed_stride)
        self.slots = np.arange(batch.n)
        self._obs = np.zeros((batch.n, batch.card.obs_dim), np.float32)
        m, card = batch.walker.model, batch.card  # the feet's bodies: the contact points, then the feet
        self._points = np.array([m.body(name).id for name in (*card.foot_contact_bodies, *card.foot_bodies)])

    @property
    def num_envs(self) -> int:
        return self.batch.n

    def _start(self, slot: int) -> None:
        b = self.batch
        b.start(slot, self.next_seed, self.next_seed)
        self._j[slot], x, legs_done, dwell_left_s, elapsed = 0.0, 0.0, 0.0, 0.0, 0
        if self.random_start:
            rng = np.random.default_rng([self.next_seed, 1])  # the episode's own draws stay the evaluator's
            x, state, elapsed = start_point(b.course, rng, b.card.control_dt_s, b.control_steps)
            b.place(slot, x, state, elapsed)
            legs_done, dwell_left_s = state.legs_done, state.dwell_left_s
        self._length_s[slot] = nominal_length_s(b.course, self._limit_s - elapsed * b.card.control_dt_s, x,
                                                legs_done, dwell_left_s, self.pace_m_per_s)
        self.next_seed += self.seed_stride

    def reset(self) -> tuple[np.ndarray, np.ndarray]:
        """Start every robot's episode; their first observations and privileged views."""
        for slot in self.slots:
            self._start(int(slot))
        self._obs = self.batch.observe(self.slots)
        return self._obs, self.privileged(self.slots)

    def privileged(self, slots: np.ndarray) -> np.ndarray:
        """What the critic may see besides the observation (module docstring), ``[len(slots), PRIVILEGED_DIM]``."""
        b = self.batch
        state = b.state[slots]
        qpos, qvel = b._qpos(state), b._qvel(state)
        lin = rotate_inverse(qpos[:, 3:7], qvel[:, 0:3], np)
        friction = np.array([b.models[s].geom_friction[b.walker.floor, 0] for s in slots])
        payload = np.array([b.episodes[s].draws.get("payload_kg", 0.0) if b.episodes[s] else 0.0 for s in slots])
        dwell = b.course_state.dwell_left_s[slots] / max(b.course.dwell_s, 1e-6)
        left = 1.0 - b.steps[slots] / b.control_steps
        legs = b.course_state.legs_done[slots] / max(b.course.legs, 1)
        return np.column_stack([lin, qpos[:, 2], friction, payload / 5.0, dwell, left, legs]).astype(np.float32)

    def reading(self, slots: np.ndarray, action: np.ndarray, last_action: np.ndarray) -> lr.LocomotionReading:
        """What the locomotion terms read of ``slots`` after their control step (a leading robot axis), as the MJX
        env reads one env after its step: the base and joints from the state; the feet from each slot's
        ``MjData`` (its kinematics at the start of the last physics step, as ``mj_step`` leaves them: what
        ``data.xpos``/``data.xmat`` hold after ``mjx.step``); the step's command and gait clock."""
        b, n = self.batch, len(slots)
        state = b.state[slots]
        qpos, qvel = b._qpos(state), b._qvel(state)
        quat = qpos[:, 3:7]
        xpos = np.stack([b.datas[s].xpos for s in slots])[:, self._points]  # whole arrays, then the feet: faster
        xmat = np.stack([b.datas[s].xmat for s in slots])[:, self._points[2:]]
        command = np.column_stack([b.command[slots, 0], np.zeros(n), b.command[slots, 1]])
        return lr.LocomotionReading(
            command=command, lin_vel_body=rotate_inverse(quat, qvel[:, 0:3], np), ang_vel_body=qvel[:, 3:6],
            gravity_body=projected_gravity(quat, np), action=action, last_action=last_action,
            q=qpos[:, b.walker.qpos_adr], default_q=b.default, phase=b.phase[slots], foot_z=xpos[:, 0:2, 2],
            feet_xy=xpos[:, 2:4, 0:2], feet_gravity_xy=-xmat[:, :, 6:8], base_yaw=crs.heading_yaw(quat, np))

    def _locomotion(self, slots: np.ndarray, action: np.ndarray, last_action: np.ndarray) -> tuple[np.ndarray, dict]:
        b = self.batch
        reading = self.reading(slots, action, last_action)
        raw = {k: np.broadcast_to(lr.TERMS[k](reading, np, **self.params.get(k, {})), (len(slots),))
               for k in self.weights}
        dt = b.card.control_dt_s
        total = sum(float(self.weights[k]) * raw[k] for k in self.weights) * dt
        return np.asarray(total, dtype=np.float64), {k: float(np.mean(v)) for k, v in raw.items()}

    def episode_j(self, slots: np.ndarray, nominal: bool = False) -> np.ndarray:
        """The J each slot's episode would report if it ended now (:func:`running_objective_j`); ``nominal``:
        its rates over the episode's nominal length instead of the time it has run (module docstring)."""
        b, s = self.batch, self.batch.sums
        fell = s.errors[slots] > 0
        length_s = self._length_s[slots] if nominal else \
            cf.rate_length_s(s.steps[slots] * b.card.physics_dt_s, b.limit_s(slots), fell, np)
        return running_objective_j(self.objective, self.economics, units=s.units[slots], errors=s.errors[slots],
                                   energy_wh=s.energy_wh[slots], length_s=length_s, fell=fell)

    def step(self, actions: np.ndarray) -> StepOut:
        """One control step of every robot with ``actions`` ``[N, num_dofs]``; ended episodes restart."""
        b, slots = self.batch, self.slots
        errors_before = b.sums.errors[slots].copy()
        last_action = b.last_action[slots].copy()
        done = b.act(slots, actions)
        j = self.episode_j(slots, nominal=True)
        econ = self.gain * (j - self._j[slots])
        self._j[slots] = j
        ended = np.flatnonzero(done)
        # the step that ends an episode settles it: J over the episode's own length, not the nominal one
        econ[ended] += self.gain * (self.episode_j(slots[ended]) - j[ended])
        loco, terms = self._locomotion(slots, b.last_action[slots], last_action)
        n, dim = b.n, b.card.obs_dim
        out = StepOut(obs=self._obs, privileged=np.zeros((n, PRIVILEGED_DIM), np.float32),
                      reward=loco + econ, terminated=np.zeros(n, bool), truncated=np.zeros(n, bool),
                      terminal_obs=np.zeros((n, dim), np.float32),
                      terminal_privileged=np.zeros((n, PRIVILEGED_DIM), np.float32),
                      terms={**terms, "locomotion": float(loco.mean()), "economic": float(econ.mean()),
                             **({"pace_m_per_s": self.pace_m_per_s} if self.pace == "walker" else {})})
        if len(ended):
            out.terminal_obs[ended] = b.observation(ended)
            out.terminal_privileged[ended] = self.privileged(ended)
            fell = b.sums.errors[slots][ended] > errors_before[ended]
            out.terminated[ended], out.truncated[ended] = fell, ~fell
            for slot in ended:
                episode = b.finish(int(slot))
                out.episodes.append(episode)
                if self.pace == "walker" and episode["walking_s"] >= 1.0:
                    self.pace_m_per_s += PACE_WEIGHT * (episode["achieved_speed_m_per_s"] - self.pace_m_per_s)
                self._start(int(slot))
        self._obs = out.obs = b.observe(slots)
        out.privileged = self.privileged(slots)
        return out

    def close(self) -> None:
        self.batch.close()
