"""An mjx run's deployable policy: ``policy.onnx``, the actor with the mujoco backend's metadata keys (bounds
from the run config), in Holosoma's format for a task on a real robot (an env with a robot card), so
Holosoma's inference stack and the sim-to-sim evaluator run what was trained here."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import jax

from econmotor.couriers.onnx_export import export_onnx
from econmotor.couriers.policy_import import holosoma_export_metadata
from econmotor.motor_backend.mjx import ppo
from econmotor.robots import card as robot_card

ONNX_FILE = "policy.onnx"
ONNX_METADATA_KEYS = ("task_id", "overlay", "overlay_references", "objective", "datapack_ids", "economics",
                      "algorithm", "obs_layout", "action_layout", "seed", "init_policy")


def export_run_policy(run_dir: Path, learner: ppo.Learner, cfg: ppo.PPOConfig, config: dict[str, Any]) -> Path:
    """Write ``run_dir/policy.onnx`` of ``learner`` (the run's ``config``: its metadata, action bounds and robot)."""
    learner = jax.device_get(learner)
    stats = (learner.stats.mean, learner.stats.var) if cfg.normalize_obs else None
    metadata = {key: config.get(key) for key in ONNX_METADATA_KEYS}
    action = config["action_layout"]
    holosoma = holosoma_export_metadata(robot_card(config["robot"])) if config.get("robot") else None
    return export_onnx(learner.params, stats, cfg.clip_obs, action["low"], action["high"],
                       run_dir / ONNX_FILE, metadata, activation=cfg.activation, holosoma=holosoma)
