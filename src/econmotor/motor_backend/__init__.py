"""Motor backends: train, evaluate and deploy motor policies (spec: motor_backends.md)."""

from econmotor.config.datapacks import (
    DatapackBundle,
    DatapackConfig,
    DatapackProvider,
    load_datapack_configs,
    save_datapack_config,
)
from econmotor.motor_backend.base import MotorBackendBase, PolicyHandle, ProgressFn
from econmotor.motor_backend.factory import known_backends, make_motor_backend, register_motor_backend
from econmotor.motor_backend.results import EvalProvenance, MotorEvalResult, MotorTrainingResult, summarize_episodes

__all__ = [
    "DatapackBundle",
    "DatapackConfig",
    "DatapackProvider",
    "EvalProvenance",
    "MotorBackendBase",
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
