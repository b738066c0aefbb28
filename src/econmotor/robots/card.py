"""RobotCard: what every part of econmotor needs to know about one real robot, written once.

A card is a frozen value: the robot's MJCF (a file inside an installed package, read offline),
its joints in the policy's order, default pose, PD gains, action scale and clip, effort limits,
torso, feet, the fall rule, the collision filter its maker's simulator applies, and the
observation convention of its maker's inference stack (:class:`ObservationConvention`). The
trainer (``motor_backend/mjx``), the policy importer and the walker env that prices them
(``couriers/``) and the meter read these fields; none of them branches on a
robot's name. Building the MuJoCo model from a card is :mod:`econmotor.robots.model`, the
observation :mod:`econmotor.robots.observation`.

This package imports NumPy and MuJoCo only, so the main interpreter (NumPy 2, MuJoCo 3.x, JAX)
and ``.venv-holosoma`` (NumPy 1.x, MuJoCo 4.x) both load it;
``tests/integration/test_robot_cards.py`` holds every fact to Holosoma's own presets.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ObservationConvention:
    """How the policy's ``actor_obs`` row is built (holosoma_inference's ``ObservationConfig`` and task).

    ``terms``: the concatenation order, holosoma_inference's group terms *sorted by name*;
    ``dims`` / ``scales``: per term (each term times its scale); ``history_length``: frames per
    term, oldest first; ``use_phase`` / ``gait_period_s``: the two feet's gait clock, advanced by
    ``2 pi / (control_rate_hz * gait_period_s)`` per control step, both feet at pi while the
    command is below ``stand_eps`` (m/s and rad/s), restarting at (0, pi) when it rises again.
    """

    terms: tuple[str, ...]
    dims: Mapping[str, int]
    scales: Mapping[str, float]
    history_length: int = 1
    use_phase: bool = True
    gait_period_s: float = 1.0
    stand_eps: float = 0.01

    @property
    def obs_dim(self) -> int:
        """Width of one ``actor_obs`` row: ``sum(dims) * history_length``."""
        return sum(self.dims[t] for t in self.terms) * self.history_length


#: holosoma_inference's locomotion ``actor_obs`` terms, sorted: the order it concatenates them in
LOCOMOTION_TERMS = tuple(sorted(("base_ang_vel", "projected_gravity", "command_lin_vel", "command_ang_vel", "dof_pos",
                                 "dof_vel", "actions", "sin_phase", "cos_phase")))
#: what Holosoma's two locomotion robots share (G1 and T1: the same simulator rates, action
#: convention, command ranges, push preset and collision filter), and econmotor's fall rule
HOLOSOMA_LOCOMOTION = {
    "mjcf_package": "holosoma", "mjcf_install": "pip install --no-deps holosoma==0.0.3",
    "action_scale": 0.25, "action_clip": 100.0, "physics_dt_s": 1.0 / 200.0, "decimation": 4,
    "self_collisions": False, "fall_tilt_rad": 0.8, "fall_height_fraction": 0.5,
    # the shipped walkers' command ranges (their ONNX metadata; holosoma's locomotion command preset)
    "command_ranges": {"lin_vel_x": (-1.0, 1.0), "lin_vel_y": (-1.0, 1.0), "ang_vel_yaw": (-1.0, 1.0)},
    "push_preset": {"push_interval_s": (5.0, 10.0), "max_push_vel": (1.0, 1.0)},
    "foot_contact_bodies": ("left_foot_contact_point", "right_foot_contact_point"),
}


def locomotion_observation(num_dofs: int, scales: Mapping[str, float], gait_period_s: float = 1.0,
                           history_length: int = 1) -> ObservationConvention:
    """holosoma_inference's locomotion observation for a robot of ``num_dofs`` joints, with its ``scales``
    (one per term of :data:`LOCOMOTION_TERMS`)."""
    per_joint = {"actions", "dof_pos", "dof_vel"}
    widths = {"base_ang_vel": 3, "projected_gravity": 3, "command_lin_vel": 2, "command_ang_vel": 1,
              "sin_phase": 2, "cos_phase": 2}
    dims = {t: num_dofs if t in per_joint else widths[t] for t in LOCOMOTION_TERMS}
    return ObservationConvention(terms=LOCOMOTION_TERMS, dims=dims,
                                 scales={t: float(scales[t]) for t in LOCOMOTION_TERMS},
                                 history_length=history_length, use_phase=True, gait_period_s=gait_period_s)


@dataclass(frozen=True)
class MotorModel:
    """The joint motors' losses the meter counts beyond the drivetrain's efficiency: winding heat.

    A joint holding torque ``tau_j`` draws current whether it moves or not, and the current heats the
    windings: ``P_heat = sum_j k_j tau_j^2`` W
    (:func:`econmotor.economics.courier_formulas.winding_heat_w`), ``k_j = R_j / (K_t,j G_j)^2`` from a
    motor datasheet (winding resistance, torque constant, gear ratio) where one is published.

    - ``heat_w_per_nm2``: ``k_j`` per joint (the card's ``dof_names`` order), W per (N m)^2;
    - ``basis``: ``"datasheet"`` or ``"calibrated"``; ``source``: the datasheet, or the figure the
      coefficients are calibrated to and how (:func:`scaled_heat_model`).
    """

    heat_w_per_nm2: tuple[float, ...]
    basis: str
    source: str

    def __post_init__(self) -> None:
        if self.basis not in ("datasheet", "calibrated"):
            raise ValueError(f"motor model basis must be 'datasheet' or 'calibrated', got {self.basis!r}")
        if any(not (k >= 0.0) for k in self.heat_w_per_nm2):
            raise ValueError("motor model heat_w_per_nm2 must be >= 0 W/(N m)^2 per joint")


def scaled_heat_model(effort_limits: tuple[float, ...], heat_at_limit_w_per_nm: float, source: str) -> MotorModel:
    """A calibrated :class:`MotorModel` where no datasheet is published: every joint's winding heat at its
    effort limit is proportional to that limit, ``k_j tau_max,j^2 = a tau_max,j``, so
    ``k_j = a / tau_max,j`` (W per (N m)^2; ``a = heat_at_limit_w_per_nm``, W per N m of peak torque).

    Why this shape: a bigger joint carries a bigger motor (or gear) whose losses at its own peak grow
    with the torque it is built for, not with its square; one constant ``a`` is then fitted to the
    maker's stated runtime (``source`` says to what and how).
    """
    return MotorModel(tuple(heat_at_limit_w_per_nm / float(t) for t in effort_limits), "calibrated", source)


@dataclass(frozen=True)
class StatedRuntime:
    """The maker's stated runtime per charge: ``hours`` of ``activity`` (e.g. "continuous operation"),
    and where it is stated (``source``)."""

    hours: float
    activity: str
    source: str


@dataclass(frozen=True)
class RobotCard:
    """One robot's facts (module docstring). Joint-indexed tuples follow ``dof_names``.

    - ``mjcf_package`` / ``mjcf_file``: the MJCF inside an installed package (found without
      importing it); ``mjcf_install``: how to install that package when it is missing.
    - ``kp`` (N m/rad), ``kd`` (N m s/rad), ``effort_limits`` (N m): the PD loop at the physics
      rate, ``tau = clip(kp (default + action_scale * action - q) - kd qd, -limit, limit)``;
      ``action_clip``: the policy output is clipped to +-this first.
    - ``physics_dt_s`` and ``decimation``: physics steps per policy step (``control_dt_s``).
    - ``init_pos``: the root's start position, m; the root starts upright.
    - ``torso_body``: tilt is read from the root quaternion (the pelvis), the torso is where a
      payload is carried; ``foot_bodies`` / ``foot_geoms``: the feet and their colliders (the
      geoms MJX lets touch the floor); ``foot_contact_bodies``: the points under the soles whose
      height the gait reward tracks (Holosoma's ``key_bodies``).
    - fall rule: tilt past ``fall_tilt_rad`` or the root below ``fall_height_fraction * init_pos[2]``;
      the runaway rule: a non-finite state or the root faster than ``runaway_speed_m_per_s`` (a
      blow-up with the base upright is a fall, not a score:
      :func:`econmotor.couriers.physics.has_fallen`, in training and pricing alike).
    - collision filter: ``self_collisions`` False as in Holosoma's MuJoCo simulator (robot
      geoms collide with the floor only).
    - ``push_preset``: Holosoma's locomotion push term (``push_randomizer_state``: ``push_interval_s``
      range, s, and ``max_push_vel`` in x and y, m/s), what a datapack's ``pushes: true`` means.
    """

    name: str
    mjcf_package: str
    mjcf_file: str
    mjcf_install: str
    dof_names: tuple[str, ...]
    default_dof_angles: tuple[float, ...]
    kp: tuple[float, ...]
    kd: tuple[float, ...]
    effort_limits: tuple[float, ...]
    action_scale: float
    action_clip: float
    physics_dt_s: float
    decimation: int
    init_pos: tuple[float, float, float]
    root_body: str
    torso_body: str
    foot_bodies: tuple[str, str]
    foot_geoms: tuple[str, ...]
    foot_contact_bodies: tuple[str, str]
    fall_tilt_rad: float
    fall_height_fraction: float
    self_collisions: bool
    command_ranges: Mapping[str, tuple[float, float]]
    observation: ObservationConvention
    push_preset: Mapping[str, tuple[float, float]]
    holosoma_experiment: str
    inference_preset: str
    sources: Mapping[str, str] = field(default_factory=dict)
    #: the joint motors' winding heat (None: the meter counts drivetrain efficiency and idle draw only)
    motor_model: MotorModel | None = None
    #: the maker's runtime per charge (the report sets the meter's beside it); None: not stated
    stated_runtime: StatedRuntime | None = None
    #: m/s: a walker moves at ~1 m/s and a push adds a few; past this the state has blown up
    runaway_speed_m_per_s: float = 20.0

    def __post_init__(self) -> None:
        n = len(self.dof_names)
        for key in ("default_dof_angles", "kp", "kd", "effort_limits"):
            if len(getattr(self, key)) != n:
                raise ValueError(f"robot card {self.name}: {key} has {len(getattr(self, key))} values "
                                 f"for {n} dof_names")
        if self.motor_model is not None and len(self.motor_model.heat_w_per_nm2) != n:
            raise ValueError(f"robot card {self.name}: motor_model has {len(self.motor_model.heat_w_per_nm2)} "
                             f"coefficients for {n} dof_names")
        if self.observation.dims.get("actions", n) != n or self.observation.dims.get("dof_pos", n) != n:
            raise ValueError(f"robot card {self.name}: observation dims disagree with {n} dof_names")

    @property
    def num_dofs(self) -> int:
        return len(self.dof_names)

    @property
    def control_dt_s(self) -> float:
        """One policy step: ``physics_dt_s * decimation``."""
        return self.physics_dt_s * self.decimation

    @property
    def control_rate_hz(self) -> float:
        return 1.0 / self.control_dt_s

    @property
    def obs_dim(self) -> int:
        return self.observation.obs_dim

    @property
    def min_base_z_m(self) -> float:
        """The fall rule's height: the root below this is on the ground."""
        return self.fall_height_fraction * self.init_pos[2]

    @property
    def phase_dt(self) -> float:
        """The gait clock's advance per control step, rad."""
        return 2.0 * np.pi / (self.control_rate_hz * self.observation.gait_period_s)

    def heat_coeff(self, dtype: type = np.float64) -> np.ndarray:
        """The winding-heat coefficients ``k_j`` (W per (N m)^2) per joint; zeros without a motor model."""
        if self.motor_model is None:
            return np.zeros(self.num_dofs, dtype=dtype)
        return np.asarray(self.motor_model.heat_w_per_nm2, dtype=dtype)

    def array(self, key: str, dtype: type = np.float64) -> np.ndarray:
        """A joint-indexed field as an array (``kp``, ``kd``, ``default_dof_angles``, ``effort_limits``)."""
        return np.asarray(getattr(self, key), dtype=dtype)
