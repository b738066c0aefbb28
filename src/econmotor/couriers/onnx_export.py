"""ONNX deployment of an MLP walker (the mjx and mujoco trainers' actors), built node by node with
``onnx.helper`` (no torch in the loop).

The graph computes, for observations ``obs`` [batch, obs_dim] (float32), exactly the
actor's deterministic action (``mjx/ppo.deterministic_action``, the mujoco walker trainer's mean)::

    x = clip((obs - mean) / sqrt(var + eps), -clip_obs, clip_obs)   # Sub, Div, Clip (if normalised)
    [x = x[:, index]]                                                 # Gather (``obs_index``)
    h = f(LN(x W1 + b1)) ... f(LN(h W_{k-1} + b_{k-1}))               # MatMul, Add, f: Tanh | Elu | Relu |
                                                                      #   Sigmoid * x (silu); [LN: layer
                                                                      #   normalisation, ``layer_norms``]
    z = h W_k + b_k;  [z = tanh(z) * scale + bias]                    # [Tanh, Mul, Add: ``squash``]
    action = min(max(z, low), high)                                   # the Gaussian's mean, clipped

An imported normaliser (``normaliser=(mean, std, clip)``) is written as it was read: ``(obs - mean) / std``,
clipped only with a clip. A layer normalisation is written as torch exports ``nn.LayerNorm`` at opset 13
(ReduceMean, Sub, Pow, ReduceMean, Add eps, Sqrt, Div, Mul, Add), as Holosoma's FastSAC files have it:
with those options the export is Holosoma's FastSAC actor layout (``onnx_actor`` reads it back).

The batch axis is dynamic. Two formats:

- econmotor's (the couriers'): input ``obs``, output ``action``, one ``econmotor`` metadata entry,
  the same JSON the mujoco backend writes (task id, compiled overlay, datapack ids, economic
  assumptions, observation / action layout, ...);
- Holosoma's (``holosoma=`` the robot's export metadata, ``policy_import.holosoma_export_metadata``):
  input ``actor_obs``, output ``action``, opset 13, Holosoma's entries (``dof_names``, ``kp``, ``kd``,
  ``action_scale``, ``command_ranges``, ``observation_layout``, ...) each JSON-encoded as Holosoma's
  exporter writes them, and ours as ``econmotor_<key>`` entries (JSON, as the holosoma backend
  attaches them): holosoma_inference's loader, which ``json.loads`` every entry, and the sim-to-sim
  evaluator's importer both read the file.

Either is served by every backend's onnxruntime handle (:class:`econmotor.motor_backend.onnx_policy.OnnxPolicyHandle`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.couriers.onnx_metadata import ECONMOTOR_PREFIX, METADATA_KEY

#: VecNormalize's epsilon inside the square root (the mjx normaliser's too)
NORM_EPS = 1e-8
#: the hidden layers' activations an actor may have (each a graph op, or Sigmoid * x for silu)
ACTIVATIONS = ("tanh", "elu", "relu", "silu")
#: Holosoma's exporter writes opset 13 (``torch.onnx.export(..., opset_version=13)``); every op here has it
OPSET = 13


def metadata_entries(metadata: Mapping[str, Any], holosoma: Mapping[str, Any] | None) -> dict[str, str]:
    """The ONNX ``metadata_props`` of either format (module docstring), every value JSON."""
    if holosoma is None:
        return {METADATA_KEY: json.dumps(dict(metadata), default=str)}
    entries = {key: json.dumps(value, default=str) for key, value in holosoma.items()}
    entries.update({f"{ECONMOTOR_PREFIX}{key}": json.dumps(value, default=str) for key, value in metadata.items()})
    return entries


def export_onnx(params: Mapping[str, Any], stats: tuple[np.ndarray, np.ndarray] | None, clip_obs: float,
                action_low: np.ndarray, action_high: np.ndarray, path: str | Path,
                metadata: Mapping[str, Any], activation: str = "tanh",
                holosoma: Mapping[str, Any] | None = None, *,
                normaliser: tuple[np.ndarray, np.ndarray, float | None] | None = None,
                obs_index: np.ndarray | None = None, layer_norms: Sequence[Mapping[str, Any]] = (),
                layer_norm_eps: float = 1e-5, squash: Mapping[str, Any] | None = None, obs_dim: int | None = None
                ) -> Path:
    """Write the deterministic policy graph to ``path`` (atomically).

    Args:
        params: the networks' parameters (``networks.init_params`` layout); only ``policy`` is used.
        stats: ``(mean, var)`` of the observation normaliser, or None when observations are raw.
        clip_obs: clip of the normalised observations.
        action_low / action_high: the env's action bounds.
        path: where ``policy.onnx`` goes.
        metadata: JSON-able dict of econmotor's metadata (task, objective, economics, layouts, ...).
        activation: the hidden layers' activation (``networks.ACTIVATIONS``).
        holosoma: Holosoma's export metadata of the robot (None: econmotor's format).
        normaliser: ``(mean, std, clip or None)``, an imported normaliser (instead of ``stats``).
        obs_index: the observation entries the first layer reads (None: all, in order); ``obs_dim`` the
            observation's width then (None: the first layer's).
        layer_norms: ``[{"w": [h], "b": [h]}]``, one per hidden layer (empty: none); ``layer_norm_eps``.
        squash: ``{"scale": [out], "bias": [out]}``: a tanh-squashed head (None: none).
    """
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    if activation not in ACTIVATIONS:
        raise ValueError(f"activation must be one of {sorted(ACTIVATIONS)}, not {activation!r}")
    if stats is not None and normaliser is not None:
        raise ValueError("a normaliser's stats or an imported normaliser, not both")
    if obs_index is not None and obs_dim is None:
        raise ValueError("an observation selection (obs_index) needs the observation's width (obs_dim)")
    if layer_norms and len(layer_norms) != len(params["policy"]) - 1:
        raise ValueError(f"{len(layer_norms)} layer norms for {len(params['policy']) - 1} hidden layers")

    f32 = lambda a: np.asarray(a, dtype=np.float32)
    inits, nodes = [], []

    def const(name: str, value: Any) -> str:
        inits.append(numpy_helper.from_array(f32(value), name))
        return name

    layers = params["policy"]
    obs_dim = int(obs_dim if obs_index is not None else np.shape(layers[0]["w"])[0])
    act_dim = int(np.shape(layers[-1]["w"])[1])
    input_name = "obs" if holosoma is None else "actor_obs"
    x = input_name
    if stats is not None:
        normaliser = (stats[0], np.sqrt(f32(stats[1]) + NORM_EPS), clip_obs)
    if normaliser is not None:
        mean, std, clip = normaliser
        nodes += [helper.make_node("Sub", [x, const("obs_mean", mean)], ["obs_centred"]),
                  helper.make_node("Div", ["obs_centred", const("obs_std", std)], ["obs_scaled"])]
        x = "obs_scaled"
        if clip is not None:
            nodes.append(helper.make_node("Clip", [x, const("clip_lo", -clip), const("clip_hi", clip)], ["obs_norm"]))
            x = "obs_norm"
    if obs_index is not None:
        inits.append(numpy_helper.from_array(np.asarray(obs_index, np.int64), "obs_index"))
        nodes.append(helper.make_node("Gather", [x, "obs_index"], ["obs_selected"], axis=1))
        x = "obs_selected"
    for i, layer in enumerate(layers):
        nodes += [helper.make_node("MatMul", [x, const(f"w{i}", layer["w"])], [f"mm{i}"]),
                  helper.make_node("Add", [f"mm{i}", const(f"b{i}", layer["b"])], [f"z{i}"])]
        x = f"z{i}"
        if i < len(layers) - 1 and layer_norms:
            nodes += _layer_norm_nodes(x, f"ln{i}", const, layer_norms[i], layer_norm_eps)
            x = f"ln{i}"
        if i < len(layers) - 1:
            if activation == "silu":
                nodes += [helper.make_node("Sigmoid", [x], [f"s{i}"]), helper.make_node("Mul", [x, f"s{i}"], [f"h{i}"])]
            else:
                op = {"tanh": "Tanh", "elu": "Elu", "relu": "Relu"}[activation]
                nodes.append(helper.make_node(op, [x], [f"h{i}"]))
            x = f"h{i}"
    if squash is not None:
        nodes += [helper.make_node("Tanh", [x], ["squashed"]),
                  helper.make_node("Mul", ["squashed", const("action_scale", squash["scale"])], ["scaled"]),
                  helper.make_node("Add", ["scaled", const("action_bias", squash["bias"])], ["squashed_action"])]
        x = "squashed_action"
    nodes += [helper.make_node("Max", [x, const("action_low", action_low)], ["action_above_low"]),
              helper.make_node("Min", ["action_above_low", const("action_high", action_high)], ["action"])]
    graph = helper.make_graph(
        nodes, "econmotor_mjx_policy",
        [helper.make_tensor_value_info(input_name, TensorProto.FLOAT, ["batch", obs_dim])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, ["batch", act_dim])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", OPSET)], producer_name="econmotor")
    model.ir_version = min(model.ir_version, 9)  # readable by onnxruntime >= 1.17
    for key, value in metadata_entries(metadata, holosoma).items():
        entry = model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(model)
    path = Path(path)
    tmp = path.with_name(path.stem + ".tmp.onnx")
    onnx.save(model, str(tmp))
    os.replace(tmp, path)
    return path


def _layer_norm_nodes(x: str, out: str, const: Any, norm: Mapping[str, Any], eps: float) -> list[Any]:
    """``out = (x - mean) / sqrt(var + eps) * w + b`` over the last axis, as torch exports ``nn.LayerNorm``."""
    from onnx import helper

    n = lambda op, inputs, name, **attrs: helper.make_node(op, inputs, [f"{out}_{name}"], **attrs)
    return [n("ReduceMean", [x], "mean", axes=[-1]), n("Sub", [x, f"{out}_mean"], "centred"),
            n("Pow", [f"{out}_centred", const(f"{out}_two", np.float32(2.0))], "square"),
            n("ReduceMean", [f"{out}_square"], "var", axes=[-1]),
            n("Add", [f"{out}_var", const(f"{out}_eps", np.float32(eps))], "var_eps"),
            n("Sqrt", [f"{out}_var_eps"], "std"), n("Div", [f"{out}_centred", f"{out}_std"], "unit"),
            n("Mul", [f"{out}_unit", const(f"{out}_w", norm["w"])], "scaled"),
            helper.make_node("Add", [f"{out}_scaled", const(f"{out}_b", norm["b"])], [out])]

