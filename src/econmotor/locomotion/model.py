"""A card robot's MuJoCo model with the PD law inside its actuators, for the walker env.

:func:`pd_actuator_spec` turns the card's model (:func:`econmotor.robots.model.model_spec`: the maker's
MJCF, the floor, the maker's collision filter, the physics step) into one whose actuators apply
``tau = clip(kp (target - q) - kd qd, -limit, limit)`` (gain ``kp`` on the target, bias ``-kp q - kd
qd``, force range the effort limits): the law Holosoma's simulators apply, computed by MuJoCo at
every physics step, and adds one ``actuatorfrc`` sensor per actuator for the meter.
:class:`WalkerModel` is the compiled model and where to read it.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from econmotor.robots import RobotCard
from econmotor.robots.model import FLOOR, joint_indices, model_spec

#: the state a walker's robots are saved and restored in (``mujoco.rollout``'s layout: time, qpos, qvel, ...)
FULL_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def pd_actuator_spec(card: RobotCard, kp: np.ndarray, kd: np.ndarray) -> mujoco.MjSpec:
    """The card's model with the PD law in its actuators (card joint order), and one ``actuatorfrc``
    sensor per actuator (named ``econmotor_frc_<joint>``)."""
    spec = model_spec(card)
    model = spec.compile()
    _, _, actuators = joint_indices(model, card)
    limit = card.array("effort_limits")
    for j, a in enumerate(actuators):
        act = spec.actuators[int(a)]
        if abs(float(act.gear[0]) - 1.0) > 1e-12:
            raise ValueError(f"robot card {card.name}: actuator {act.name} has gear {act.gear[0]}, PD by "
                             "actuators assumes 1 (torque = actuator force)")
        act.gaintype, act.biastype = mujoco.mjtGain.mjGAIN_FIXED, mujoco.mjtBias.mjBIAS_AFFINE
        act.gainprm[0] = kp[j]
        act.biasprm[0], act.biasprm[1], act.biasprm[2] = 0.0, -kp[j], -kd[j]
        act.forcerange, act.forcelimited = [-limit[j], limit[j]], mujoco.mjtLimited.mjLIMITED_TRUE
        act.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        spec.add_sensor(name=f"econmotor_frc_{card.dof_names[j]}", type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
                        objtype=mujoco.mjtObj.mjOBJ_ACTUATOR, objname=act.name)
    return spec


def set_pd_gains(model: mujoco.MjModel, actuators: np.ndarray, kp: np.ndarray, kd: np.ndarray) -> None:
    """Set the PD law's gains of a model built by :func:`pd_actuator_spec` (per joint, card order)."""
    model.actuator_gainprm[actuators, 0] = kp
    model.actuator_biasprm[actuators, 1] = -kp
    model.actuator_biasprm[actuators, 2] = -kd


@dataclass
class WalkerModel:
    """The compiled PD-actuated model of a card and where to read it (card joint order)."""

    card: RobotCard
    model: mujoco.MjModel
    qpos_adr: np.ndarray
    dof_adr: np.ndarray
    actuators: np.ndarray
    frc_adr: np.ndarray  # the actuator-force sensors in sensordata
    torso: int
    floor: int
    kp: np.ndarray
    kd: np.ndarray

    @classmethod
    def build(cls, card: RobotCard, kp: np.ndarray | None = None, kd: np.ndarray | None = None) -> WalkerModel:
        """The card's model with PD gains ``kp``/``kd`` (default: the card's; an imported policy's own)."""
        kp = card.array("kp") if kp is None else np.asarray(kp, dtype=np.float64)
        kd = card.array("kd") if kd is None else np.asarray(kd, dtype=np.float64)
        model = pd_actuator_spec(card, kp, kd).compile()
        qpos_adr, dof_adr, actuators = joint_indices(model, card)
        frc = np.asarray([model.sensor_adr[model.sensor(f"econmotor_frc_{n}").id] for n in card.dof_names])
        return cls(card, model, qpos_adr, dof_adr, actuators, frc, model.body(card.torso_body).id,
                   model.geom(FLOOR).id, kp, kd)

    @property
    def nstate(self) -> int:
        return mujoco.mj_stateSize(self.model, FULL_STATE)
