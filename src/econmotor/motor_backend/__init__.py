"""Motor backends: train, evaluate and deploy motor policies (spec: motor_backends.md)."""

from econmotor.motor_backend.base import (
    EvalProvenance,
    MotorBackend,
    MotorEvalResult,
    MotorTrainingResult,
    PolicyHandle,
    ProgressFn,
    summarize_episodes,
)
from econmotor.motor_backend.datapacks import (
    DatapackBundle,
    DatapackConfig,
    DatapackProvider,
    load_datapack_configs,
    save_datapack_config,
)
from econmotor.motor_backend.factory import known_backends, make_motor_backend, register_motor_backend

__all__ = [
    "DatapackBundle",
    "DatapackConfig",
    "DatapackProvider",
    "EvalProvenance",
    "MotorBackend",
    "MotorEvalResult",
    "MotorTrainingResult",
    "PolicyHandle",
    "ProgressFn",
    "known_backends",
    "load_datapack_configs",
    "make_motor_backend",
    "register_motor_backend",
    "save_datapack_config",
    "summarize_episodes",
]
