"""The ``mjx`` motor backend: the mujoco couriers on MuJoCo's JAX port, batched on a GPU or CPU.

One env shape: thin single envs over a pytree ``State`` (``base_env.py``; ``env.py``: the Gymnasium
bodies, ``humanoid_env.py``: the G1/T1), batched, auto-reset and metered by wrappers (``wrappers.py``),
pure jit/vmap functions with the economics (``econmotor.economics.courier_formulas``) inside the step.
"""
