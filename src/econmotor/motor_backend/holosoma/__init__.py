"""Holosoma backend internals.

Two interpreters meet here, in two folders. The main environment (numpy 2) imports the host side,
:mod:`.host` (the backend, its plan, the recording's metrics and the subprocess client that hands the
runner a :mod:`.job_specs` dataclass as JSON); none of it imports Holosoma or torch.
The isolated ``.venv-holosoma`` (numpy 1.x, Holosoma, torch) runs the venv side, :mod:`.venv`:
its runner (``python -m econmotor.motor_backend.holosoma.venv.runner JOB.json``), its recording
(an eval callback) and its reward terms. Locomotion policies are priced in the main interpreter by
the walker env (:mod:`econmotor.locomotion.evaluation`). Everything shared between the
two sides is a typed job (:mod:`.job_specs`, parsed once by the runner), plain JSON or
array-agnostic arithmetic (:mod:`.econ_formulas`), so it runs unchanged on numpy 1.x, numpy 2
and torch.
"""
