"""ONNX deployment of an mjx policy, built node by node with ``onnx.helper`` (no torch in the loop).

The graph computes, for observations ``obs`` [batch, obs_dim] (float32), exactly
``ppo.deterministic_action``::

    x = clip((obs - mean) / sqrt(var + eps), -clip_obs, clip_obs)   # Sub, Div, Clip (if normalised)
    h = tanh(x W1 + b1) ... tanh(h W_{k-1} + b_{k-1})                 # MatMul, Add, Tanh
    action = min(max(h W_k + b_k, low), high)                         # the Gaussian's mean, clipped

The batch axis is dynamic. The ``econmotor`` metadata entry is the same JSON the mujoco
backend writes (task id, compiled overlay, datapack ids, economic assumptions, observation /
action layout, ...). The handle is the couriers' onnxruntime handle with ``step`` as an
alias of ``act``.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.motor_backend.couriers.onnx_policy import METADATA_KEY, OnnxPolicyHandle
from econmotor.motor_backend.mjx.networks import NORM_EPS

OPSET = 17


def export_onnx(params: Mapping[str, Any], stats: tuple[np.ndarray, np.ndarray] | None, clip_obs: float,
                action_low: np.ndarray, action_high: np.ndarray, path: str | Path,
                metadata: Mapping[str, Any]) -> Path:
    """Write the deterministic policy graph to ``path`` (atomically).

    Args:
        params: the networks' parameters (``networks.init_params`` layout); only ``policy`` is used.
        stats: ``(mean, var)`` of the observation normaliser, or None when observations are raw.
        clip_obs: clip of the normalised observations.
        action_low / action_high: the env's action bounds.
        path: where ``policy.onnx`` goes.
        metadata: JSON-able dict stored under the ``econmotor`` metadata key.
    """
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    f32 = lambda a: np.asarray(a, dtype=np.float32)
    inits, nodes = [], []

    def const(name: str, value: Any) -> str:
        inits.append(numpy_helper.from_array(f32(value), name))
        return name

    layers = params["policy"]
    obs_dim = int(np.shape(layers[0]["w"])[0])
    act_dim = int(np.shape(layers[-1]["w"])[1])
    x = "obs"
    if stats is not None:
        mean, var = stats
        nodes += [helper.make_node("Sub", [x, const("obs_mean", mean)], ["obs_centred"]),
                  helper.make_node("Div", ["obs_centred", const("obs_std", np.sqrt(f32(var) + NORM_EPS))],
                                   ["obs_scaled"]),
                  helper.make_node("Clip", ["obs_scaled", const("clip_lo", -clip_obs), const("clip_hi", clip_obs)],
                                   ["obs_norm"])]
        x = "obs_norm"
    for i, layer in enumerate(layers):
        nodes += [helper.make_node("MatMul", [x, const(f"w{i}", layer["w"])], [f"mm{i}"]),
                  helper.make_node("Add", [f"mm{i}", const(f"b{i}", layer["b"])], [f"z{i}"])]
        x = f"z{i}"
        if i < len(layers) - 1:
            nodes.append(helper.make_node("Tanh", [x], [f"h{i}"]))
            x = f"h{i}"
    nodes += [helper.make_node("Max", [x, const("action_low", action_low)], ["action_above_low"]),
              helper.make_node("Min", ["action_above_low", const("action_high", action_high)], ["action"])]
    graph = helper.make_graph(
        nodes, "econmotor_mjx_policy",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", obs_dim])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", act_dim])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="econmotor")
    model.ir_version = min(model.ir_version, 9)  # readable by onnxruntime >= 1.17
    entry = model.metadata_props.add()
    entry.key, entry.value = METADATA_KEY, json.dumps(dict(metadata), default=str)
    onnx.checker.check_model(model)
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp.onnx")
    onnx.save(model, str(tmp))
    os.replace(tmp, path)
    return path


class MjxOnnxPolicyHandle(OnnxPolicyHandle):
    """onnxruntime handle on an exported mjx policy: ``act(obs)`` (one or a batch) and ``step`` (alias)."""

    def step(self, obs: np.ndarray) -> np.ndarray:
        return self.act(obs)
