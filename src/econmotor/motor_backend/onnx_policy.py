"""The one onnxruntime handle of an exported policy, for every backend that deploys ONNX.

Two metadata formats (:mod:`econmotor.couriers.onnx_metadata`): econmotor's (the mujoco and mjx backends'
couriers' ``policy.onnx``), one ``econmotor`` entry (JSON: task id, compiled overlay, datapack ids,
economic assumptions, observation / action layout); and Holosoma's (the holosoma backend's runs and
imports, the mjx backend's real robots),
Holosoma's own entries (``dof_names``, ``kp``, ``kd``, ``action_scale``, ...) each JSON-encoded, with
econmotor's facts beside them as ``econmotor_<key>`` entries. :class:`OnnxPolicyHandle` reads either
(:func:`econmotor_metadata`). No torch or jax here: the handle also runs in .venv-holosoma (numpy 1.x),
where the sim-to-sim evaluator steps it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from econmotor.couriers.onnx_metadata import ECONMOTOR_PREFIX, METADATA_KEY, econmotor_metadata, json_or_text
from econmotor.errors import BackendError
from econmotor.motor_backend.base import StepAlias


class OnnxPolicyHandle(StepAlias):
    """A deployed policy on onnxruntime (one intra-op and one inter-op thread): ``act(obs)`` (or
    ``step(obs)``) for one observation ``[obs_dim]`` or a batch ``[n, obs_dim]``.

    Args:
        path: the exported ONNX file.

    Attributes:
        path: the file; obs_dim, action_dim: input and output widths.
        metadata: econmotor's (task id, objective, overlay, task economics, layouts, ...), either format.
        holosoma_metadata: Holosoma's entries, JSON-decoded (empty for econmotor's format).
        dof_names, kp, kd, action_scale: Holosoma's joint order, PD gains and action scaling
            (joint target = default_pos + action_scale * action); empty / None without them.
        takes_time_step: the graph also takes ``time_step``, the motion clip's frame (whole-body-tracking
            exports); such graphs, and graphs with a fixed batch of 1, are run a row at a time.
    """

    def __init__(self, path: str | Path) -> None:
        import onnxruntime as ort

        from econmotor.couriers.onnx_file import onnx_session

        self.path = Path(path)
        if not self.path.is_file():
            raise BackendError(f"no ONNX policy at {self.path}; train or export one first")
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        self.session = onnx_session(self.path, self.path, options)
        raw = self.session.get_modelmeta().custom_metadata_map
        self.metadata: dict[str, Any] = econmotor_metadata(raw)
        self.holosoma_metadata = {k: json_or_text(v) for k, v in raw.items()
                                  if k != METADATA_KEY and not k.startswith(ECONMOTOR_PREFIX)}
        self.dof_names: list[str] = list(self.holosoma_metadata.get("dof_names", []))
        self.kp = self.holosoma_metadata.get("kp")
        self.kd = self.holosoma_metadata.get("kd")
        self.action_scale = self.holosoma_metadata.get("action_scale")
        inputs = self.session.get_inputs()
        self._input = inputs[0].name  # "obs", or Holosoma's "actor_obs"
        self._output = self.session.get_outputs()[0].name  # "action"
        self.takes_time_step = any(i.name == "time_step" for i in inputs)
        self._rowwise = self.takes_time_step or inputs[0].shape[0] == 1
        self.obs_dim = int(inputs[0].shape[-1])
        self.action_dim = int(self.session.get_outputs()[0].shape[-1])

    def act(self, obs: np.ndarray, time_step: int = 0) -> np.ndarray:
        """Deterministic action(s) for ``obs`` [obs_dim] or [n, obs_dim] (float32); a whole-body-tracking
        export also takes the motion clip's ``time_step`` (frame index)."""
        x = np.asarray(obs, dtype=np.float32)
        if x.shape == (1, self.obs_dim) and not self.takes_time_step:  # one row, as an evaluator steps it
            return self.session.run([self._output], {self._input: x})[0]
        single = x.ndim == 1
        batch = x[None, :] if single else x
        if batch.shape[-1] != self.obs_dim:
            raise BackendError(f"observation width {batch.shape[-1]} does not match the policy's {self.obs_dim}")
        if self._rowwise:
            feeds = [{self._input: row[None, :]} for row in batch]
            if self.takes_time_step:
                for feed in feeds:
                    feed["time_step"] = np.array([[time_step]], dtype=np.float32)
            out = np.concatenate([self.session.run([self._output], feed)[0] for feed in feeds])
        else:
            out = self.session.run([self._output], {self._input: batch})[0]
        return out[0] if single else out
