"""An ONNX walker's actor as arrays: what every trainer of the card robots starts from.

A team rarely trains a humanoid from nothing; it takes its maker's walker and tunes it. An ONNX
policy in Holosoma's format (a shipped one, ``holosoma:g1_29dof/ppo``, or a team's own, econmotor's
exports included) is read node by node (:func:`read_actor`) into layers ``[{"w": [in, out], "b": [out]}]``:

    [x = (obs - mean) / std]                  # Sub, Div by constants (optionally Clip): the normaliser
    h = f(x W1 + b1) ... f(h W_{k-1} + b_{k-1})  # Gemm (or MatMul + Add), f: Elu | Tanh | Relu | Sigmoid*x
    action = h W_k + b_k                       # [Max, Min by constants: econmotor's bounds, dropped]

Holosoma's PPO walkers are rsl_rl actors: 100 -> 512 -> 256 -> 128 -> 29, ELU, no normaliser in
the graph (its observation scales are in the observation). An architecture an MLP actor does not
have (Holosoma's FastSAC actors: layer normalisation and a tanh-squashed head) is a ConfigError
naming the node it stopped at. The mjx trainer (``mjx/onnx_import.py``, JAX) and the mujoco walker
trainer (``mujoco/walker_ppo.py``, torch) both start from what this reads; both export with
:mod:`econmotor.couriers.onnx_export`.

A shipped name resolves to its file with the holosoma backend's rules
(``policy_import.parse_policy_name``; :func:`policy_file`): in this interpreter's
holosoma_inference if it has one, else in the Holosoma interpreter's (``.venv-holosoma``,
``find_holosoma_python``), found without importing either.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from econmotor.errors import ConfigError

_ACTIVATION_OPS = {"Elu": "elu", "Tanh": "tanh", "Relu": "relu"}


@dataclass(frozen=True)
class ImportedActor:
    """An ONNX actor in the mjx layout (module docstring).

    Attributes:
        path: the ONNX file; ``source``: what the user named (a shipped name or the path).
        input_name / obs_dim / action_dim: the graph's input and widths.
        layers: ``[{"w": [in, out], "b": [out]}, ...]`` (float32).
        activation: the hidden layers' activation (``networks.ACTIVATIONS``).
        obs_mean / obs_std: the in-graph normaliser (None: raw observations); ``clip_obs`` its clip.
        metadata: the file's metadata entries, JSON-decoded.
        sha256: the file's digest (recorded with the run).
    """

    path: Path
    source: str
    input_name: str
    obs_dim: int
    action_dim: int
    layers: list[dict[str, np.ndarray]]
    activation: str
    obs_mean: np.ndarray | None = None
    obs_std: np.ndarray | None = None
    clip_obs: float | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    sha256: str = ""

    @property
    def hidden_sizes(self) -> tuple[int, ...]:
        return tuple(int(layer["w"].shape[1]) for layer in self.layers[:-1])

    def describe(self) -> dict[str, Any]:
        """What the run records of its start (``run_config.json``'s ``init_policy``)."""
        return {"policy": self.source, "onnx_path": str(self.path), "sha256": self.sha256,
                "input": self.input_name, "obs_dim": self.obs_dim, "action_dim": self.action_dim,
                "hidden_sizes": list(self.hidden_sizes), "activation": self.activation,
                "normaliser_in_graph": self.obs_mean is not None}


def policy_file(policy: str, holosoma_venv: str | Path | None = None) -> Path:
    """The ONNX file of ``policy``: a shipped name (module docstring) or a path; a ConfigError otherwise."""
    import importlib.util

    from econmotor.couriers.policy_import import NAME_PREFIX, find_holosoma_python, shipped_policy_path

    if policy.startswith(NAME_PREFIX):
        here = importlib.util.find_spec("holosoma_inference") is not None
        return shipped_policy_path(policy, None if here else find_holosoma_python(holosoma_venv), "--init-policy")
    path = Path(policy)
    if path.suffix != ".onnx" or not path.is_file():
        raise ConfigError("--init-policy", policy, "no such ONNX file",
                          "an ONNX file in Holosoma's format or a shipped name such as holosoma:g1_29dof/ppo")
    return path


def policy_command_ranges(policy: str) -> dict[str, Any]:
    """The command ranges ``policy`` was trained for, from its ONNX metadata (Holosoma's ``command_ranges``:
    ``lin_vel_x`` [min, max] m/s, ...): a shipped name, an ONNX file or a run directory's ``policy.onnx``.
    ``{}`` when it declares none or is not found (the command's own checks name a bad policy)."""
    import os

    from econmotor.couriers.policy_import import VENV_ENV, onnx_metadata
    from econmotor.errors import EconmotorError

    run_file = Path(policy) / "policy.onnx"
    try:
        path = run_file if run_file.is_file() else policy_file(policy, os.environ.get(VENV_ENV))
        return dict(onnx_metadata(path).get("command_ranges") or {})
    except EconmotorError:
        return {}


def _decode(value: str) -> Any:
    from econmotor.couriers.onnx_metadata import json_or_text

    return json_or_text(value)


def read_actor(path: str | Path, source: str | None = None) -> ImportedActor:
    """The actor of an ONNX file (module docstring); a ConfigError names the node it cannot read."""
    import onnx
    from onnx import numpy_helper

    from econmotor.couriers.onnx_file import load_onnx

    path = Path(path)
    where = source or str(path)
    model = load_onnx(path, source)
    graph = model.graph
    consts = {i.name: numpy_helper.to_array(i).astype(np.float32) for i in graph.initializer}
    for node in graph.node:
        if node.op_type == "Constant":
            consts[node.output[0]] = numpy_helper.to_array(node.attribute[0].t).astype(np.float32)
    if len(graph.input) != 1 or len(graph.output) != 1:
        raise ConfigError(where, "inputs", f"an actor takes one input and gives one output, this graph has "
                          f"{[i.name for i in graph.input]} -> {[o.name for o in graph.output]}")
    current = graph.input[0].name
    layers: list[dict[str, np.ndarray]] = []
    activations: set[str] = set()
    mean = std = clip = None
    pending_matmul: np.ndarray | None = None
    nodes = [n for n in graph.node if n.op_type != "Constant"]
    i = 0
    while i < len(nodes):
        node = nodes[i]
        args = [a for a in node.input if a != current]
        if current not in node.input:
            raise ConfigError(where, f"node {node.name or node.op_type}", "the graph is not one chain of layers "
                              "(an MLP actor)")
        op = node.op_type
        attrs = {a.name: onnx.helper.get_attribute_value(a) for a in node.attribute}
        if op == "Gemm":
            if attrs.get("alpha", 1.0) != 1.0 or attrs.get("beta", 1.0) != 1.0 or attrs.get("transA", 0):
                raise ConfigError(where, f"node {node.name}", f"a Gemm with {attrs} (an MLP layer is x W + b)")
            w = consts[node.input[1]]
            layers.append({"w": w.T if attrs.get("transB", 0) else w, "b": consts[node.input[2]].reshape(-1)})
        elif op == "MatMul" and node.input[0] == current:
            pending_matmul = consts[node.input[1]]
        elif op == "Add" and pending_matmul is not None:
            layers.append({"w": pending_matmul, "b": consts[args[0]].reshape(-1)})
            pending_matmul = None
        elif op in _ACTIVATION_OPS and layers and (op != "Elu" or attrs.get("alpha", 1.0) == 1.0):
            activations.add(_ACTIVATION_OPS[op])
        elif op == "Sigmoid" and layers and i + 1 < len(nodes) and nodes[i + 1].op_type == "Mul" \
                and set(nodes[i + 1].input) == {current, node.output[0]}:
            activations.add("silu")
            i += 1
            node = nodes[i]
        elif op == "Sub" and not layers and mean is None and node.input[0] == current and args[0] in consts:
            mean = consts[args[0]].reshape(-1)
        elif op == "Div" and not layers and mean is not None and std is None and args[0] in consts:
            std = consts[args[0]].reshape(-1)
        elif op == "Clip" and not layers and std is not None and len(node.input) == 3:
            clip = float(consts[node.input[2]].reshape(-1)[0])
        elif op in ("Max", "Min") and layers and args and args[0] in consts:
            pass  # econmotor's export clips the mean to the env's bounds; the env applies them here too
        else:
            raise ConfigError(where, f"node {node.name or op} ({op})", "not an architecture an MLP actor has "
                              "(an MLP of Gemm/MatMul+Add layers with one activation: Elu, Tanh, Relu or "
                              "Sigmoid*x, optionally after a Sub/Div normaliser); Holosoma's FastSAC actors "
                              "(layer normalisation, tanh-squashed head) cannot be started from")
        current = node.output[0]
        i += 1
    if len(activations) > 1 or not layers:
        raise ConfigError(where, "layers", f"{len(layers)} layers with activations {sorted(activations)}: an MLP "
                          "actor has one activation")
    sizes = [int(layers[0]["w"].shape[0])] + [int(layer["w"].shape[1]) for layer in layers]
    for k, layer in enumerate(layers):
        if layer["w"].shape != (sizes[k], sizes[k + 1]) or layer["b"].shape != (sizes[k + 1],):
            raise ConfigError(where, f"layer {k}", f"weights {layer['w'].shape} and bias {layer['b'].shape} do "
                              f"not chain ({sizes})")
    metadata = {p.key: _decode(p.value) for p in model.metadata_props}
    return ImportedActor(path=path, source=source or str(path), input_name=graph.input[0].name, obs_dim=sizes[0],
                         action_dim=sizes[-1], layers=layers, activation=next(iter(activations), "tanh"),
                         obs_mean=mean, obs_std=std, clip_obs=clip, metadata=metadata,
                         sha256=hashlib.sha256(path.read_bytes()).hexdigest())
