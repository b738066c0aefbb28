"""The mujoco walker trainer's actor as a torch module: built from a network's arrays, and read back into them.

A network is :meth:`econmotor.couriers.onnx_actor.ImportedActor.network`'s dict (``architecture``,
``layers``, ``activation``, ``obs_dim``, ``obs_mean``, ``obs_std``, ``clip_obs``, ``obs_index``, ``layer_norms``,
``layer_norm_eps``, ``squash``): what an ONNX actor is read into, what the ONNX export writes
(``walker_training.export_walker``) and what the collect workers are sent every iteration
(``walker_collect.actor_weights``: it carries the architecture, so a worker rebuilds the same actor).
:func:`actor_module` makes it an ``nn.Sequential`` whose output is the network's deterministic action, the
mean of the PPO's Gaussian::

    [Normaliser]  (obs - mean) / std [clipped]             buffers: the imported normaliser does not move
    [Select]      obs[..., index]                          a buffer
    Linear [LayerNorm] activation ... Linear               learned: the layers, the layer norms' w and b
    [TanhHead]    tanh(z) * scale + bias                   buffers (Holosoma's FastSAC's action scale/bias)

A plain MLP (``mlp`` architecture, no normaliser or selection) is exactly :func:`mlp`'s module, so its
parameters' names (and the checkpoints of runs started from Holosoma's PPO walkers) are unchanged.
:func:`load_network` sets a module's arrays from a network of the same architecture; :func:`network_of` reads
them back.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
from torch import nn

from econmotor.motor_backend.mujoco.walker_recipe import ACTIVATIONS

_ACTIVATIONS = dict(zip(ACTIVATIONS, (nn.ELU, nn.Tanh, nn.ReLU, nn.SiLU), strict=True))
_NAMES = {module: name for name, module in _ACTIVATIONS.items()}


def _tensor(a: Any, dtype: torch.dtype = torch.float32) -> torch.Tensor:
    return torch.as_tensor(np.array(a), dtype=dtype).reshape(-1)


def _array(t: torch.Tensor) -> np.ndarray:
    return t.detach().numpy().copy()


class Normaliser(nn.Module):
    """``(x - mean) / std``, clipped to ``+-clip`` with one: an imported normaliser, fixed."""

    def __init__(self, mean: Any, std: Any, clip: float | None) -> None:
        super().__init__()
        self.register_buffer("mean", _tensor(mean))
        self.register_buffer("std", _tensor(std))
        self.clip = None if clip is None else float(clip)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = (x - self.mean) / self.std
        return x if self.clip is None else torch.clamp(x, -self.clip, self.clip)


class Select(nn.Module):
    """``x[..., index]``: the entries the first layer reads of an observation of ``width``."""

    def __init__(self, index: Any, width: int) -> None:
        super().__init__()
        self.register_buffer("index", _tensor(index, torch.long))
        self.width = int(width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x.index_select(-1, self.index)


class TanhHead(nn.Module):
    """``tanh(z) * scale + bias``: a tanh-squashed action (Holosoma's FastSAC actors)."""

    def __init__(self, scale: Any, bias: Any) -> None:
        super().__init__()
        self.register_buffer("scale", _tensor(scale))
        self.register_buffer("bias", _tensor(bias))

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        return torch.tanh(z) * self.scale + self.bias


def mlp(sizes: Sequence[int], activation: str) -> nn.Sequential:
    """Linear layers of ``sizes`` with ``activation`` between them (none after the last)."""
    layers: list[nn.Module] = []
    for i in range(len(sizes) - 1):
        layers.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(sizes) - 2:
            layers.append(_ACTIVATIONS[activation]())
    return nn.Sequential(*layers)


def load_layers(net: nn.Sequential, layers: Sequence[Mapping[str, np.ndarray]]) -> None:
    """Set the linear layers of ``net``, in order, to ``layers`` (``[{"w": [in, out], "b": [out]}]``)."""
    linears = [m for m in net if isinstance(m, nn.Linear)]
    with torch.no_grad():
        for lin, layer in zip(linears, layers, strict=True):
            lin.weight.copy_(torch.from_numpy(np.asarray(layer["w"], np.float32).T))
            lin.bias.copy_(torch.from_numpy(np.asarray(layer["b"], np.float32)))


def actor_module(network: Mapping[str, Any]) -> nn.Sequential:
    """The actor of ``network`` (module docstring), its arrays loaded."""
    layers, activation = network["layers"], network["activation"]
    sizes = [int(np.shape(layers[0]["w"])[0])] + [int(np.shape(layer["w"])[1]) for layer in layers]
    norms = network.get("layer_norms") or []
    modules: list[nn.Module] = []
    if network.get("obs_mean") is not None:
        modules.append(Normaliser(network["obs_mean"], network["obs_std"], network.get("clip_obs")))
    if network.get("obs_index") is not None:
        modules.append(Select(network["obs_index"], network["obs_dim"]))
    for i in range(len(layers)):
        modules.append(nn.Linear(sizes[i], sizes[i + 1]))
        if i < len(layers) - 1:
            if norms:
                modules.append(nn.LayerNorm(sizes[i + 1], eps=float(network["layer_norm_eps"])))
            modules.append(_ACTIVATIONS[activation]())
    if network.get("squash") is not None:
        modules.append(TanhHead(network["squash"]["scale"], network["squash"]["bias"]))
    net = nn.Sequential(*modules)
    load_network(net, network)
    return net


def _shape(network: Mapping[str, Any]) -> tuple[Any, ...]:
    """What two networks of one architecture share: widths, activation and which parts they have."""
    sizes = tuple(np.shape(layer["w"]) for layer in network["layers"])
    return (sizes, network["activation"], network.get("obs_mean") is not None, network.get("obs_index") is not None,
            len(network.get("layer_norms") or []), network.get("squash") is not None)


def load_network(net: nn.Sequential, network: Mapping[str, Any]) -> None:
    """Set ``net``'s arrays (layers, layer norms, normaliser, selection, head) to ``network``'s; a ValueError
    if ``network`` is another architecture."""
    if _shape(network_of(net)) != _shape(network):
        raise ValueError(f"a network of {_shape(network)} does not fit the actor's {_shape(network_of(net))}")
    load_layers(net, network["layers"])
    norms = iter(network.get("layer_norms") or [])
    with torch.no_grad():
        for m in net:
            if isinstance(m, nn.LayerNorm):
                norm = next(norms)
                m.weight.copy_(_tensor(norm["w"]))
                m.bias.copy_(_tensor(norm["b"]))
            elif isinstance(m, Normaliser):
                m.mean.copy_(_tensor(network["obs_mean"]))
                m.std.copy_(_tensor(network["obs_std"]))
            elif isinstance(m, Select):
                m.index.copy_(_tensor(network["obs_index"], torch.long))
            elif isinstance(m, TanhHead):
                m.scale.copy_(_tensor(network["squash"]["scale"]))
                m.bias.copy_(_tensor(network["squash"]["bias"]))


def network_of(net: nn.Sequential) -> dict[str, Any]:
    """``net``'s network (module docstring): its architecture and its arrays now (NumPy copies)."""
    linears = [m for m in net if isinstance(m, nn.Linear)]
    kinds = {type(m): m for m in net}
    norm = kinds.get(Normaliser)
    select = kinds.get(Select)
    head = kinds.get(TanhHead)
    norms = [{"w": _array(m.weight), "b": _array(m.bias)} for m in net if isinstance(m, nn.LayerNorm)]
    activation = next((name for module, name in _NAMES.items() if module in kinds), ACTIVATIONS[0])
    obs_dim = select.width if select is not None else linears[0].in_features
    return {"architecture": "fastsac" if norms or head is not None else "mlp",
            "layers": [{"w": _array(m.weight).T.copy(), "b": _array(m.bias)} for m in linears],
            "activation": activation, "obs_dim": obs_dim,
            "obs_mean": None if norm is None else _array(norm.mean),
            "obs_std": None if norm is None else _array(norm.std), "clip_obs": None if norm is None else norm.clip,
            "obs_index": None if select is None else _array(select.index),
            "layer_norms": norms, "layer_norm_eps": next((m.eps for m in net if isinstance(m, nn.LayerNorm)), 1e-5),
            "squash": None if head is None else {"scale": _array(head.scale), "bias": _array(head.bias)}}
