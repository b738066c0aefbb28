"""The card robots' (G1, T1: :mod:`econmotor.robots`) walking on the delivery course, engine- and backend-free.

What every backend that trains or prices a card robot shares, owned by none of them (it imports nothing of
:mod:`econmotor.motor_backend`; no gymnasium, torch or jax either):

- ``task.py``: a walker task's settings, meter settings and course from the task catalog,
- ``course.py``: the delivery course, one implementation for NumPy and JAX callers,
- ``stress.py``: a datapack's per-episode conditions, one reading for both walker envs,
- ``conditions.py``: what prices (and trains) a card robot on a task (``walker_setup``: contract, course,
  meter, stress),
- ``model.py``: a card's MuJoCo model with the PD law inside its actuators,
- ``env.py``: N robots per process stepped by MuJoCo C, metered (``WalkerBatch``, ``run_episodes``),
- ``learning.py``: that env as the learner sees it (``WalkerLearningEnv``: random starts, step reward,
  the critic's privileged view),
- ``rewards.py``: Holosoma's locomotion reward terms, NumPy and JAX,
- ``evaluation.py``: the one pricer, seeded episodes of the env on worker processes (``evaluate``).
"""
