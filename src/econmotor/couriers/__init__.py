"""What every backend's couriers share, owned by none of them; imports no gymnasium, torch or jax.

The walkers (the card robots, :mod:`econmotor.robots`):

- ``course.py``: the delivery course, one implementation for NumPy and JAX callers,
- ``stress.py``: a datapack's per-episode conditions; ``datapack_mapping.py``: datapacks in
  Holosoma's randomization terms,
- ``walker_task.py``: a walker task's settings, meter and course from the task catalog,
- ``policy_import.py``: a Holosoma-format ONNX walker's contract with its robot card,
- ``walker_env.py``: N robots per process stepped by MuJoCo C, metered; ``walker_eval.py``: seeded
  episodes of it on worker processes (the sim-to-sim evaluator).

The Gymnasium couriers (their robot facts: :mod:`econmotor.robots.gym_couriers`):

- ``physics.py``: what metering reads from any MuJoCo model (actuated dofs, root tilt),
- ``settings.py``: the metering settings of a catalog entry, validated once,
- ``overlay.py``: the overlay's terms, checks and human-baseline references,
- ``randomization.py``: the datapack domain-randomization and curriculum keys.

An exported courier policy is served by every backend's onnxruntime handle
(:mod:`econmotor.motor_backend.onnx_policy`).

The per-step economic formulas themselves are robot-free and live in
:mod:`econmotor.economics.courier_formulas`.
"""
