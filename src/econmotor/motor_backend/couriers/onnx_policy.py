"""The onnxruntime handle of a courier's exported policy (the mujoco and mjx backends' ``policy.onnx``).

Both backends write the deterministic actor as ONNX with the same ``econmotor`` metadata entry
(JSON: task id, compiled overlay, datapack ids, economic assumptions, observation / action
layout); this handle serves either, without torch or jax.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.errors import BackendError
from econmotor.motor_backend.base import StepAlias

#: the ONNX ``metadata_props`` key of the JSON metadata.
METADATA_KEY = "econmotor"


class OnnxPolicyHandle(StepAlias):
    """A deployed policy on onnxruntime: ``act(obs)`` (or ``step(obs)``) for one observation or a batch.

    Args:
        path: the exported ``policy.onnx``.
        threads: onnxruntime intra-op threads (1 keeps latency low on small machines).
    """

    def __init__(self, path: str | Path, threads: int = 1) -> None:
        import onnxruntime as ort

        self.path = Path(path)
        if not self.path.is_file():
            raise BackendError(f"no ONNX policy at {self.path}; train or export one first")
        options = ort.SessionOptions()
        options.intra_op_num_threads = threads
        options.inter_op_num_threads = 1
        self._session = ort.InferenceSession(str(self.path), options, providers=["CPUExecutionProvider"])
        meta = self._session.get_modelmeta().custom_metadata_map
        self.metadata: dict[str, Any] = json.loads(meta.get(METADATA_KEY, "{}"))
        self.obs_dim = int(self._session.get_inputs()[0].shape[-1])

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic action(s) for ``obs`` [obs_dim] or [batch, obs_dim]."""
        obs = np.asarray(obs, dtype=np.float32)
        single = obs.ndim == 1
        out = self._session.run(["action"], {"obs": obs[None] if single else obs})[0]
        return out[0] if single else out
