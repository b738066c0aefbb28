"""ONNX deployment: the deterministic actor (with observation normalisation) and its handle.

The exported graph computes, for observations ``obs`` [batch, obs_dim] (float32)::

    x = clip((obs - mean) / sqrt(var + eps), -clip_obs, clip_obs)     # VecNormalize, if used
    PPO: action = clip(action_net(mlp_actor(x)), low, high)           # the Gaussian's mean
    SAC: action = low + (tanh(mu(latent_pi(x))) + 1) / 2 * (high - low)

i.e. exactly SB3's ``predict(obs, deterministic=True)`` without torch.distributions (the
dynamo exporter trips on their argument validation). The batch axis is dynamic. Metadata
(``econmotor`` key of the ONNX ``metadata_props``, JSON): task id, compiled overlay,
datapack ids, economic assumptions, observation / action layout. The onnxruntime handle that
serves it is every backend's (``motor_backend/onnx_policy.py``).
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from econmotor.couriers.onnx_metadata import METADATA_KEY
from econmotor.errors import BackendError
from econmotor.motor_backend.onnx_policy import OnnxPolicyHandle

__all__ = ["METADATA_KEY", "DeterministicActor", "OnnxPolicyHandle", "export_onnx"]


class DeterministicActor(nn.Module):
    """SB3 policy -> deterministic action, normalisation folded in (formula in the module doc)."""

    def __init__(self, model: Any, normalizer: tuple[np.ndarray, np.ndarray, float, float] | None) -> None:
        super().__init__()
        space = model.action_space
        self.register_buffer("low", torch.as_tensor(space.low, dtype=torch.float32))
        self.register_buffer("high", torch.as_tensor(space.high, dtype=torch.float32))
        if normalizer is not None:
            mean, var, eps, clip = normalizer
            self.register_buffer("mean", torch.as_tensor(mean, dtype=torch.float32))
            self.register_buffer("inv_std", torch.as_tensor(1.0 / np.sqrt(var + eps), dtype=torch.float32))
            self.clip_obs = float(clip)
        self.normalize = normalizer is not None
        policy = model.policy
        self.sac = hasattr(policy, "actor") and hasattr(policy.actor, "mu")
        if self.sac:
            actor = policy.actor
            self.features, self.latent, self.head = actor.features_extractor, actor.latent_pi, actor.mu
        else:
            self.features, self.latent, self.head = policy.pi_features_extractor, policy.mlp_extractor.policy_net, \
                policy.action_net

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        if self.normalize:
            obs = torch.clamp((obs - self.mean) * self.inv_std, -self.clip_obs, self.clip_obs)
        out = self.head(self.latent(self.features(obs)))
        if self.sac:
            return self.low + (torch.tanh(out) + 1.0) * 0.5 * (self.high - self.low)
        return torch.maximum(torch.minimum(out, self.high), self.low)


def export_onnx(model: Any, normalizer: tuple[np.ndarray, np.ndarray, float, float] | None,
                path: str | Path, metadata: Mapping[str, Any]) -> Path:
    """Export the deterministic actor of an SB3 PPO/SAC ``model`` to ``path`` with ``metadata``."""
    import onnx

    path = Path(path)
    actor = DeterministicActor(model, normalizer).eval()
    obs_dim = int(np.prod(model.observation_space.shape))
    example = torch.zeros(2, obs_dim, dtype=torch.float32)
    tmp = path.with_name(path.stem + ".tmp.onnx")
    try:  # the TorchScript exporter: the dynamo one needs onnxscript and trips on distributions
        with torch.no_grad(), warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            torch.onnx.export(actor, (example,), str(tmp), input_names=["obs"], output_names=["action"],
                              dynamo=False, dynamic_axes={"obs": {0: "batch"}, "action": {0: "batch"}},
                              opset_version=17)
    except Exception as exc:  # the exporter raises many unrelated types
        raise BackendError(f"ONNX export of {type(model).__name__} failed: {exc}") from exc
    proto = onnx.load(str(tmp))
    entry = proto.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, json.dumps(dict(metadata), default=str)
    onnx.save(proto, str(tmp))
    tmp.replace(path)
    return path
