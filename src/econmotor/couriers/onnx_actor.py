"""An ONNX walker's actor as arrays: what every trainer of the card robots starts from.

A team rarely trains a humanoid from nothing; it takes its maker's walker and tunes it. An ONNX
policy in Holosoma's format (a shipped one, ``holosoma:g1_29dof/ppo`` or ``holosoma:g1_29dof/fastsac``,
or a team's own, econmotor's exports included) is read node by node (:func:`read_actor`) into layers
``[{"w": [in, out], "b": [out]}]`` and what surrounds them:

    [x = (obs - mean) / std]                  # Sub, Div by constants (optionally Clip): the normaliser
    [x = x[..., index]]                       # Slice(s) + Concat, or Gather, on the last axis
    h = f(LN(x W1 + b1)) ... f(LN(h W_{k-1} + b_{k-1}))  # Gemm (or MatMul + Add), f: Elu | Tanh | Relu |
                                              #   Sigmoid*x; [LN: layer normalisation, after every hidden
                                              #   layer or none: LayerNormalization or its decomposition]
    z = h W_k + b_k
    action = z  or  tanh(z) * scale + bias    # [Tanh, Mul, Add by constants: the tanh-squashed head]
                                              # [Max, Min by constants: econmotor's bounds, dropped]

Two architectures (:attr:`ImportedActor.architecture`): ``mlp``, Holosoma's PPO walkers (rsl_rl actors:
100 -> 512 -> 256 -> 128 -> 29, ELU, no normaliser in the graph: its observation scales are in the
observation), and ``fastsac``, an MLP with layer normalisation and/or a tanh-squashed head, Holosoma's
FastSAC walkers (``holosoma/agents/fast_sac``'s ``Actor`` behind its ``EmpiricalNormalization``: the
normaliser, a Slice of all 100 observation entries and a Concat of it, 100 -> 512 -> 256 -> 128 each
Gemm, layer norm (eps 1e-5), SiLU, then ``tanh(z) * action_scale + action_bias`` to 29). Anything else
is a ConfigError naming the node it stopped at. The mujoco walker trainer (``mujoco/walker_ppo.py``,
torch) starts from both; the mjx trainer (``mjx/onnx_import.py``, JAX) from ``mlp`` actors only. Both
export with :mod:`econmotor.couriers.onnx_export`.

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
#: torch's ``nn.LayerNorm`` epsilon (Holosoma's FastSAC actors use its default)
LAYER_NORM_EPS = 1e-5


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
        obs_index: the (normalised) observation's entries the first layer reads, in order (None: all of them).
        layer_norms: ``[{"w": [h], "b": [h]}]``, one per hidden layer, after its linear map and before its
            activation (empty: none); ``layer_norm_eps`` their epsilon.
        squash: ``{"scale": [out], "bias": [out]}``: the action is ``tanh(z) * scale + bias`` of the last
            layer's ``z`` (None: ``z``).
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
    obs_index: np.ndarray | None = None
    layer_norms: list[dict[str, np.ndarray]] = field(default_factory=list)
    layer_norm_eps: float = LAYER_NORM_EPS
    squash: dict[str, np.ndarray] | None = None

    @property
    def hidden_sizes(self) -> tuple[int, ...]:
        return tuple(int(layer["w"].shape[1]) for layer in self.layers[:-1])

    @property
    def architecture(self) -> str:
        """``mlp`` or ``fastsac`` (layer normalisation and/or a tanh-squashed head: module docstring)."""
        return "fastsac" if self.layer_norms or self.squash is not None else "mlp"

    def network(self) -> dict[str, Any]:
        """The actor's network as arrays, what a trainer builds its actor from and the export writes
        (``architecture``, ``layers``, ``activation``, ``obs_dim``, ``obs_mean``, ``obs_std``, ``clip_obs``,
        ``obs_index``, ``layer_norms``, ``layer_norm_eps``, ``squash``: the attributes of those names)."""
        return {"architecture": self.architecture, "layers": self.layers, "activation": self.activation,
                "obs_dim": self.obs_dim, "obs_mean": self.obs_mean, "obs_std": self.obs_std, "clip_obs": self.clip_obs,
                "obs_index": self.obs_index, "layer_norms": self.layer_norms,
                "layer_norm_eps": self.layer_norm_eps, "squash": self.squash}

    def describe(self) -> dict[str, Any]:
        """What the run records of its start (``run_config.json``'s ``init_policy``)."""
        return {"policy": self.source, "onnx_path": str(self.path), "sha256": self.sha256,
                "input": self.input_name, "obs_dim": self.obs_dim, "action_dim": self.action_dim,
                "architecture": self.architecture, "hidden_sizes": list(self.hidden_sizes),
                "activation": self.activation, "normaliser_in_graph": self.obs_mean is not None,
                "layer_norm": bool(self.layer_norms), "tanh_squashed": self.squash is not None}


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


_UNKNOWN = ("not an architecture an actor here has (an MLP of Gemm/MatMul+Add layers with one activation: Elu, "
            "Tanh, Relu or Sigmoid*x, optionally after a Sub/Div normaliser and a Slice/Concat or Gather of the "
            "observation, optionally with a layer normalisation after every hidden layer and a tanh-squashed "
            "head, tanh(z) * scale + bias: Holosoma's PPO and FastSAC actors)")
#: a layer normalisation as torch exports it at opset 13 (``nn.LayerNorm`` decomposed)
_LAYER_NORM_OPS = ["ReduceMean", "Sub", "Pow", "ReduceMean", "Add", "Sqrt", "Div", "Mul", "Add"]


def _attrs(node: Any) -> dict[str, Any]:
    import onnx

    return {a.name: onnx.helper.get_attribute_value(a) for a in node.attribute}


def _layer_norm(nodes: list[Any], i: int, x: str, consts: dict[str, np.ndarray]
                ) -> tuple[dict[str, np.ndarray], float, int] | None:
    """The layer normalisation over the last axis of ``x`` starting at ``nodes[i]``: ``({"w", "b"}, eps, the
    nodes it spans)``; None if it is not one (a LayerNormalization op or its decomposition)."""
    node = nodes[i]
    if node.op_type == "LayerNormalization":
        a = _attrs(node)
        if a.get("axis", -1) != -1 or node.input[0] != x or node.input[1] not in consts:
            return None
        w = consts[node.input[1]].reshape(-1)
        b = consts[node.input[2]].reshape(-1) if len(node.input) > 2 and node.input[2] else np.zeros_like(w)
        return {"w": w, "b": b}, float(a.get("epsilon", LAYER_NORM_EPS)), 1
    span = nodes[i:i + len(_LAYER_NORM_OPS)]
    if [n.op_type for n in span] != _LAYER_NORM_OPS:
        return None
    mu, sub, square, var, add, sqrt, div, mul, shift = span
    out = lambda n: n.output[0]
    other = lambda n, name: next((a for a in n.input if a != name), "")
    last_axis = all(_attrs(n).get("axes") == [-1] and _attrs(n).get("keepdims", 1) == 1 for n in (mu, var))
    if not (last_axis and list(mu.input) == [x] and list(sub.input) == [x, out(mu)]
            and square.input[0] == out(sub) and consts.get(square.input[1], np.zeros(1)).reshape(-1)[0] == 2.0
            and list(var.input) == [out(square)] and out(var) in add.input and other(add, out(var)) in consts
            and list(sqrt.input) == [out(add)] and list(div.input) == [out(sub), out(sqrt)]
            and out(div) in mul.input and other(mul, out(div)) in consts
            and out(mul) in shift.input and other(shift, out(mul)) in consts):
        return None
    eps = float(consts[other(add, out(var))].reshape(-1)[0])
    return {"w": consts[other(mul, out(div))].reshape(-1), "b": consts[other(shift, out(mul))].reshape(-1)}, eps, 9


def _selection(nodes: list[Any], i: int, x: str, raw: dict[str, np.ndarray], width: int | None
               ) -> tuple[np.ndarray, int] | None:
    """The entries of ``x``'s last axis that ``nodes[i]`` on select (Slices on that axis, concatenated if more
    than one, or a Gather), and the nodes it spans; None if it is not such a selection."""
    if width is None:
        return None
    entries = np.arange(width)
    if nodes[i].op_type == "Gather":
        index = raw.get(nodes[i].input[1])
        if _attrs(nodes[i]).get("axis", 0) not in (1, -1) or index is None:
            return None
        return entries[index.astype(np.int64).reshape(-1)], 1
    picked, outs, j = [], [], i
    while j < len(nodes) and nodes[j].op_type == "Slice" and nodes[j].input[0] == x:
        args = [raw.get(a) if a else None for a in nodes[j].input[1:]] + [None, None]
        starts, ends, axes, steps = args[:4]
        if starts is None or ends is None or starts.size != 1 or axes is None \
                or int(axes.reshape(-1)[0]) not in (1, -1):
            return None
        step = 1 if steps is None else int(steps.reshape(-1)[0])
        picked.append(entries[int(starts.reshape(-1)[0]):int(ends.reshape(-1)[0]):step])
        outs.append(nodes[j].output[0])
        j += 1
    if not picked:
        return None
    if j < len(nodes) and nodes[j].op_type == "Concat" and list(nodes[j].input) == outs \
            and _attrs(nodes[j]).get("axis") in (1, -1):
        return np.concatenate(picked), j + 1 - i
    return (picked[0], 1) if len(picked) == 1 else None


def _input_width(value_info: Any) -> int | None:
    dims = value_info.type.tensor_type.shape.dim
    return int(dims[-1].dim_value) if len(dims) == 2 and dims[-1].HasField("dim_value") else None


def read_actor(path: str | Path, source: str | None = None) -> ImportedActor:
    """The actor of an ONNX file (module docstring); a ConfigError names the node it cannot read."""
    from onnx import numpy_helper

    from econmotor.couriers.onnx_file import load_onnx

    path = Path(path)
    where = source or str(path)
    model = load_onnx(path, source)
    graph = model.graph
    raw = {i.name: numpy_helper.to_array(i) for i in graph.initializer}
    for node in graph.node:
        if node.op_type == "Constant":
            raw[node.output[0]] = numpy_helper.to_array(node.attribute[0].t)
    consts = {name: value.astype(np.float32) for name, value in raw.items()}
    if len(graph.input) != 1 or len(graph.output) != 1:
        raise ConfigError(where, "inputs", f"an actor takes one input and gives one output, this graph has "
                          f"{[i.name for i in graph.input]} -> {[o.name for o in graph.output]}")
    current = graph.input[0].name
    width = _input_width(graph.input[0])
    layers: list[dict[str, np.ndarray]] = []
    norms: dict[int, dict[str, np.ndarray]] = {}
    epsilons: set[float] = set()
    activations: set[str] = set()
    mean = std = clip = index = squash = None
    pending_matmul: np.ndarray | None = None
    after_layer = False  # the last node completed a layer
    nodes = [n for n in graph.node if n.op_type != "Constant"]
    i = 0
    while i < len(nodes):
        node = nodes[i]
        args = [a for a in node.input if a != current]
        if current not in node.input:
            raise ConfigError(where, f"node {node.name or node.op_type}", "the graph is not one chain of layers "
                              "(an MLP actor)")
        op, attrs, span = node.op_type, _attrs(node), 1
        last_layer = not any(n.op_type in ("Gemm", "MatMul") for n in nodes[i + 1:])
        norm = _layer_norm(nodes, i, current, consts) if after_layer and not last_layer else None
        chosen = _selection(nodes, i, current, raw, width) if not layers and index is None else None
        completes = False
        if op == "Gemm" and squash is None:
            if attrs.get("alpha", 1.0) != 1.0 or attrs.get("beta", 1.0) != 1.0 or attrs.get("transA", 0):
                raise ConfigError(where, f"node {node.name}", f"a Gemm with {attrs} (an MLP layer is x W + b)")
            w = consts[node.input[1]]
            layers.append({"w": w.T if attrs.get("transB", 0) else w, "b": consts[node.input[2]].reshape(-1)})
            completes = True
        elif op == "MatMul" and node.input[0] == current and squash is None:
            pending_matmul = consts[node.input[1]]
        elif op == "Add" and pending_matmul is not None:
            layers.append({"w": pending_matmul, "b": consts[args[0]].reshape(-1)})
            pending_matmul, completes = None, True
        elif norm is not None:
            norms[len(layers) - 1], span = norm[0], norm[2]
            epsilons.add(norm[1])
        elif op == "Tanh" and after_layer and last_layer:
            squash = {"scale": None, "bias": None}  # tanh(z) * scale + bias: the Mul and Add that follow
        elif op in _ACTIVATION_OPS and layers and squash is None and (op != "Elu" or attrs.get("alpha", 1.0) == 1.0):
            activations.add(_ACTIVATION_OPS[op])
        elif op == "Sigmoid" and layers and squash is None and i + 1 < len(nodes) and nodes[i + 1].op_type == "Mul" \
                and set(nodes[i + 1].input) == {current, node.output[0]}:
            activations.add("silu")
            span = 2
        elif op == "Mul" and squash is not None and squash["scale"] is None and squash["bias"] is None \
                and args and args[0] in consts:
            squash["scale"] = consts[args[0]]
        elif op == "Add" and squash is not None and squash["bias"] is None and args and args[0] in consts:
            squash["bias"] = consts[args[0]]
        elif op == "Sub" and not layers and index is None and mean is None and node.input[0] == current \
                and args[0] in consts:
            mean = consts[args[0]].reshape(-1)
        elif op == "Div" and not layers and index is None and mean is not None and std is None and args[0] in consts:
            std = consts[args[0]].reshape(-1)
        elif op == "Clip" and not layers and index is None and std is not None and len(node.input) == 3:
            clip = float(consts[node.input[2]].reshape(-1)[0])
        elif chosen is not None:
            index, span = chosen
        elif op in ("Max", "Min") and layers and args and args[0] in consts:
            pass  # econmotor's export clips the mean to the env's bounds; the env applies them here too
        else:
            raise ConfigError(where, f"node {node.name or op} ({op})", _UNKNOWN)
        after_layer = completes
        current = nodes[i + span - 1].output[0]
        i += span
    if len(activations) > 1 or not layers:
        raise ConfigError(where, "layers", f"{len(layers)} layers with activations {sorted(activations)}: an MLP "
                          "actor has one activation")
    sizes = [int(layers[0]["w"].shape[0])] + [int(layer["w"].shape[1]) for layer in layers]
    for k, layer in enumerate(layers):
        if layer["w"].shape != (sizes[k], sizes[k + 1]) or layer["b"].shape != (sizes[k + 1],):
            raise ConfigError(where, f"layer {k}", f"weights {layer['w'].shape} and bias {layer['b'].shape} do "
                              f"not chain ({sizes})")
    if norms and (sorted(norms) != list(range(len(layers) - 1)) or len(epsilons) != 1
                  or any(norms[k][p].shape != (sizes[k + 1],) for k in norms for p in ("w", "b"))):
        raise ConfigError(where, "layer norms", f"after hidden layers {sorted(norms)} of {len(layers) - 1} (epsilons "
                          f"{sorted(epsilons)}): an actor normalises every hidden layer, one epsilon, or none")
    if squash is not None:  # a missing Mul is a scale of 1, a missing Add a bias of 0
        given = {k: np.full(1, float(k == "scale"), np.float32) if v is None else v.reshape(-1)
                 for k, v in squash.items()}
        if any(v.size not in (1, sizes[-1]) for v in given.values()):
            raise ConfigError(where, "tanh head", f"scale and bias of {[v.size for v in given.values()]} values for "
                              f"{sizes[-1]} actions")
        squash = {k: np.broadcast_to(v, (sizes[-1],)).astype(np.float32) for k, v in given.items()}
    if index is not None:
        if len(index) != sizes[0]:
            raise ConfigError(where, "input selection", f"{len(index)} observation entries for a first layer of "
                              f"{sizes[0]} inputs")
        index = None if np.array_equal(index, np.arange(width)) else index.astype(np.int64)
    metadata = {p.key: _decode(p.value) for p in model.metadata_props}
    return ImportedActor(path=path, source=source or str(path), input_name=graph.input[0].name,
                         obs_dim=width if index is not None else sizes[0], action_dim=sizes[-1], layers=layers,
                         activation=next(iter(activations), "tanh"), obs_mean=mean, obs_std=std, clip_obs=clip,
                         metadata=metadata, sha256=hashlib.sha256(path.read_bytes()).hexdigest(), obs_index=index,
                         layer_norms=[norms[k] for k in sorted(norms)],
                         layer_norm_eps=next(iter(epsilons), LAYER_NORM_EPS), squash=squash)
