"""What every backend's couriers share, owned by none of them; imports no gymnasium, torch or jax.

The walkers (the card robots, :mod:`econmotor.robots`; their walking itself, course, stress, env and
pricer, is :mod:`econmotor.locomotion`):

- ``datapack_mapping.py``: datapacks in Holosoma's randomization terms,
- ``policy_import.py``: a Holosoma-format ONNX walker's contract with its robot card,
- ``onnx_file.py``, ``onnx_metadata.py``, ``onnx_actor.py``, ``onnx_export.py``: an ONNX file opened,
  econmotor's ONNX metadata, an ONNX actor read into arrays and written in either ONNX format.

The Gymnasium couriers (their robot facts: :mod:`econmotor.robots.gym_couriers`):

- ``physics.py``: what metering reads from any MuJoCo model (actuated dofs, root tilt; the card robots'
  fall rule too),
- ``settings.py``: the metering settings of a catalog entry, validated once,
- ``overlay.py``: the overlay's terms, checks and human-baseline references,
- ``randomization.py``: the datapack domain-randomization and curriculum keys.

An exported courier policy is served by every backend's onnxruntime handle
(:mod:`econmotor.motor_backend.onnx_policy`).

The per-step economic formulas themselves are robot-free and live in
:mod:`econmotor.economics.courier_formulas`.
"""
