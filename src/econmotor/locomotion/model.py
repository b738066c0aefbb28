"""A card robot's MuJoCo model with the PD law inside its actuators, for both engines.

The law ``tau = clip(kp (target - q) - kd qd, -limit, limit)`` (Holosoma's simulators') is written
once, here: :func:`pd_actuator_spec` turns the card's model (:func:`econmotor.robots.model.model_spec`:
the maker's MJCF, the floor, the maker's collision filter, the physics step; ``contacts`` as there)
into one whose actuators apply it (gain ``kp`` on ``ctrl = target``, bias ``-kp q - kd qd``, force
range the card's effort limits; the MJCF's control range is dropped: the G1's hip roll motors say
+-88 where the card and the joints' ``actuatorfrcrange`` say +-139), computed by MuJoCo at every
physics step, and adds one ``actuatorfrc``
sensor per actuator for the meter. :func:`pd_gain_bias` gives the actuator parameters of other
gains, for a NumPy ``MjModel`` (:func:`set_pd_gains`, the walker env's per-episode gains) and an MJX
model alike (``model.replace(actuator_gainprm=..., actuator_biasprm=...)``, the MJX humanoid env's).
Under the Euler integrator (the cards' MJCFs') the ``kd`` term is explicit, as when the law is
computed outside MuJoCo; ``implicitfast`` would integrate it implicitly (actuator velocity derivatives).
:class:`WalkerModel` is the compiled model and where to read it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from econmotor.robots import RobotCard
from econmotor.robots.model import FLOOR, joint_indices, model_spec

#: the state a walker's robots are saved and restored in (``mujoco.rollout``'s layout: time, qpos, qvel, ...)
FULL_STATE = mujoco.mjtState.mjSTATE_FULLPHYSICS


def pd_actuator_spec(card: RobotCard, kp: np.ndarray, kd: np.ndarray, *, contacts: str = "robot") -> mujoco.MjSpec:
    """The card's model (``contacts`` as :func:`~econmotor.robots.model.model_spec`'s) with the PD law in its
    actuators (gains per joint, card joint order), and one ``actuatorfrc`` sensor per actuator (named
    ``econmotor_frc_<joint>``)."""
    spec = model_spec(card, contacts=contacts)
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


def pd_gain_bias(gainprm: Any, biasprm: Any, actuators: Any, kp: Any, kd: Any) -> tuple[Any, Any]:
    """``(actuator_gainprm, actuator_biasprm)`` of a model built by :func:`pd_actuator_spec` with the PD
    law's gains ``kp``/``kd`` (per joint, card order) at ``actuators``; NumPy or JAX arrays, the given ones
    left unchanged (a JAX array's ``.at[].set``, a NumPy array's copy)."""
    if hasattr(gainprm, "at"):  # JAX
        return (gainprm.at[actuators, 0].set(kp),
                biasprm.at[actuators, 1].set(-kp).at[actuators, 2].set(-kd))
    gain, bias = np.array(gainprm, copy=True), np.array(biasprm, copy=True)
    gain[actuators, 0], bias[actuators, 1], bias[actuators, 2] = kp, -kp, -kd
    return gain, bias


def set_pd_gains(model: mujoco.MjModel, actuators: np.ndarray, kp: np.ndarray, kd: np.ndarray) -> None:
    """Set the PD law's gains of a model built by :func:`pd_actuator_spec` (per joint, card order)."""
    model.actuator_gainprm[:], model.actuator_biasprm[:] = pd_gain_bias(
        model.actuator_gainprm, model.actuator_biasprm, actuators, kp, kd)


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
