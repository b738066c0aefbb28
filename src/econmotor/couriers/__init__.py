"""What the MuJoCo and MJX couriers share; imports no gymnasium, torch or jax.

- ``robots.py``: one :class:`~econmotor.robots.gym_couriers.CourierRobot` record per
  robot (Gymnasium v5 defaults, healthy rule, observation parts, reward and reset facts),
- ``physics.py``: what metering reads from any MuJoCo model (actuated dofs, root tilt),
- ``settings.py``: the metering settings of a catalog entry, validated once,
- ``overlay.py``: the overlay's terms, checks and human-baseline references,
- ``randomization.py``: the datapack domain-randomization and curriculum keys.

An exported courier policy is served by every backend's onnxruntime handle
(:mod:`econmotor.motor_backend.onnx_policy`).

The per-step economic formulas themselves are robot-free and live in
:mod:`econmotor.economics.courier_formulas`.
"""
