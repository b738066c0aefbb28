"""The venv side of the holosoma backend: what runs inside ``.venv-holosoma`` (NumPy 1.x, torch, Holosoma).

- :mod:`.runner`: ``python -m econmotor.motor_backend.holosoma.venv.runner JOB.json``, the job runner;
- :mod:`.reward_terms`: the economic overlay as Holosoma reward terms (referenced by name in its config);
- :mod:`.recording`: the evaluation's recording callback (Holosoma's, extended).

The host side (the package above: the backend, its plan and job launcher) never imports these
(``tests/unit/test_import_graph.py``); both sides read the job contract (:mod:`..job_specs`), the
protocol (:mod:`..protocol`) and the formulas (:mod:`..econ_formulas`).
"""
