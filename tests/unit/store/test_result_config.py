"""What a run's config records of a backend result: the backend's own keys apart from the contract's
declared provenance, which report and compare read."""

from econmotor.motor_backend.results import PROVENANCE_KEY, EvalProvenance, MotorEvalResult, MotorTrainingResult
from econmotor.store.registry import result_config


def test_an_evaluation_records_its_provenance_apart_from_the_backends_keys():
    provenance = EvalProvenance(evaluator="sim2sim", figures_from="a course", commanded_speed_m_per_s=1.0)
    result = MotorEvalResult("p", "t", "holosoma", {}, {}, config={"seed": 3}, provenance=provenance)
    assert result_config(result) == {"backend_config": {"seed": 3}, PROVENANCE_KEY: provenance.to_dict()}


def test_a_training_result_records_its_config_only():
    result = MotorTrainingResult("p", "t", "mujoco", {}, {}, config={"lr": 3e-4})
    assert result_config(result) == {"backend_config": {"lr": 3e-4}}
    assert result_config(MotorTrainingResult("p", "t", "mujoco", {}, {})) == {}
