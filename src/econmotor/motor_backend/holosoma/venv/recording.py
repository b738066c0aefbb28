"""Holosoma's evaluation recording, extended with what econ metrics need (runs in .venv-holosoma).

:class:`EconRecordingCallback` is Holosoma's ``EvalRecordingCallback`` (dof state, torques
per physics sub-step, root pose and velocities, commanded velocity, actions) plus five
channels: ``reset`` and ``time_out`` (episode flags after each step), ``reward`` (the env's step reward),
``base_lin_vel`` (base frame) and ``actor_obs`` (the policy input after each step, so a
deployed ONNX policy can be checked against the recorded next action). It also reports
progress as protocol lines every 50 steps.
"""

from __future__ import annotations

import os
from typing import Any

import torch
from holosoma.agents.callbacks.recording import EvalRecordingCallback

from econmotor.motor_backend.holosoma.protocol import emit

EXTRA_CHANNELS = ("reset", "time_out", "reward", "base_lin_vel", "actor_obs")
TOTAL_STEPS_ENV = "ECONMOTOR_EVAL_STEPS"


class EconRecordingCallback(EvalRecordingCallback):
    """Holosoma's recorder plus the econ channels (see the module docstring)."""

    def on_pre_evaluate_policy(self) -> None:
        super().on_pre_evaluate_policy()
        for name in EXTRA_CHANNELS:
            self._buffers[name] = []
        self._total_steps = int(os.environ.get(TOTAL_STEPS_ENV, "0"))

    def on_post_eval_env_step(self, actor_state: dict[str, Any]) -> dict[str, Any]:
        actor_state = super().on_post_eval_env_step(actor_state)
        env, eid = self._get_env(), self.env_id
        self._buffers["reset"].append(env.reset_buf[eid].detach().cpu().numpy().astype(bool))
        self._buffers["time_out"].append(env.time_out_buf[eid].detach().cpu().numpy().astype(bool))
        self._buffers["reward"].append(env.rew_buf[eid].detach().cpu().numpy().copy())
        try:
            from holosoma.managers.observation.terms.locomotion import get_base_lin_vel

            base_lin_vel = get_base_lin_vel(env)[eid]
        except (AttributeError, KeyError):  # envs without a base quaternion: world frame
            base_lin_vel = env.simulator.robot_root_states[eid, 7:10]
        self._buffers["base_lin_vel"].append(base_lin_vel.detach().cpu().numpy().copy())
        obs, keys = actor_state["obs"], getattr(self.training_loop, "actor_obs_keys", ["actor_obs"])
        if isinstance(obs, torch.Tensor):  # FastSAC keeps the (unnormalised) actor observation itself
            self._buffers["actor_obs"].append(obs[eid].detach().cpu().numpy().copy())
        elif all(k in obs for k in keys):  # PPO: a dict of observation groups
            actor_obs = torch.cat([obs[k] for k in keys], dim=1)[eid]
            self._buffers["actor_obs"].append(actor_obs.detach().cpu().numpy().copy())
        if self._step_count % 50 == 0 or self._step_count == self._total_steps:
            emit("progress", label="holosoma evaluate", done=self._step_count, total=self._total_steps)
        return actor_state
