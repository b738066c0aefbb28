"""The onnxruntime handle of a courier's exported policy (the mujoco and mjx backends' ``policy.onnx``).

Both backends write the deterministic actor as ONNX with the same ``econmotor`` metadata entry
(JSON: task id, compiled overlay, datapack ids, economic assumptions, observation / action
layout); a policy exported in Holosoma's format (the mjx backend's real robots, the holosoma
backend's runs) carries the same facts as ``econmotor_<key>`` entries beside Holosoma's
(:func:`econmotor_metadata` reads either). This handle serves any of them, without torch or jax.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.errors import BackendError
from econmotor.motor_backend.base import StepAlias

#: the ONNX ``metadata_props`` key of the JSON metadata.
METADATA_KEY = "econmotor"
#: in Holosoma-format files, econmotor's metadata entries are ``econmotor_<key>`` (JSON values)
ECONMOTOR_PREFIX = "econmotor_"


def json_or_text(value: str) -> Any:
    """A metadata value decoded from JSON, or the text itself when it is not JSON."""
    try:
        return json.loads(value)
    except (json.JSONDecodeError, TypeError):
        return value


def econmotor_metadata(entries: Mapping[str, str]) -> dict[str, Any]:
    """econmotor's metadata of an ONNX file's entries: the ``econmotor`` entry, else the ``econmotor_<key>`` ones."""
    if METADATA_KEY in entries:
        return json.loads(entries[METADATA_KEY])
    return {k[len(ECONMOTOR_PREFIX):]: json_or_text(v) for k, v in entries.items() if k.startswith(ECONMOTOR_PREFIX)}


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
        self.metadata: dict[str, Any] = econmotor_metadata(meta)
        self._input = self._session.get_inputs()[0].name  # "obs", or Holosoma's "actor_obs"
        self.obs_dim = int(self._session.get_inputs()[0].shape[-1])

    def act(self, obs: np.ndarray) -> np.ndarray:
        """Deterministic action(s) for ``obs`` [obs_dim] or [batch, obs_dim]."""
        obs = np.asarray(obs, dtype=np.float32)
        single = obs.ndim == 1
        out = self._session.run(["action"], {self._input: obs[None] if single else obs})[0]
        return out[0] if single else out
