"""The host side of the holosoma backend: what runs in econmotor's main interpreter (NumPy 2).

- :mod:`.backend`: ``HolosomaBackend``, the contract; locomotion policies are priced here by the
  walker env (:mod:`econmotor.locomotion.evaluation`);
- :mod:`.plan`: a Holosoma training request adapted to the machine;
- :mod:`.jobs`: the subprocess client that hands ``.venv-holosoma``'s runner a job and reads its protocol;
- :mod:`.recording_metrics`: raw metrics from Holosoma's ``eval_agent`` recording.

It never imports the venv side (:mod:`..venv`, ``tests/unit/test_import_graph.py``); both read the job
contract (:mod:`..job_specs`), the protocol (:mod:`..protocol`) and the formulas (:mod:`..econ_formulas`).
"""
