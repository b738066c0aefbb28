"""The ``mjx`` motor backend: the mujoco couriers on MuJoCo's JAX port, batched on a GPU or CPU.

``env.py``: :class:`~econmotor.motor_backend.mjx.env.MjxCourierEnv`, pure jit/vmap functions with
the economics (``econmotor.economics.courier_formulas``) inside the step.
"""
