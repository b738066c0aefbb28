"""``read_actor`` (couriers/onnx_actor.py) on Holosoma's FastSAC walkers and the layouts around them.

- the shipped G1 and T1 FastSAC files read into their architecture (normaliser, the Slice of all 100
  observation entries, three Gemm + layer norm + SiLU layers, a tanh head with the action scale), and that
  network, run here in NumPy, acts as onnxruntime runs the file;
- the PPO walkers still read as plain MLPs;
- the same layout written with the other ops an exporter may use (two Slices and a Concat, the opset-17
  LayerNormalization op, a head without a bias) reads the same way;
- a graph with an op no actor here has names that node.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
import pytest
from onnx import TensorProto, helper, numpy_helper

from econmotor.couriers.onnx_actor import ImportedActor, read_actor
from econmotor.couriers.policy_import import find_holosoma_python, shipped_policy_path
from econmotor.errors import ConfigError

REPO = Path(__file__).resolve().parents[3]
FASTSAC = ("holosoma:g1_29dof/fastsac", "holosoma:t1_29dof/fastsac")


def onnxruntime_actions(path: Path, obs: np.ndarray) -> np.ndarray:
    """The file's actions, one row at a time (Holosoma's files take a batch of one)."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    name = session.get_inputs()[0].name
    return np.concatenate([session.run(None, {name: row[None]})[0] for row in obs])


def numpy_actions(actor: ImportedActor, obs: np.ndarray) -> np.ndarray:
    """``actor``'s deterministic action computed here from what ``read_actor`` returned (float64)."""
    act = {"silu": lambda z: z / (1.0 + np.exp(-z)), "elu": lambda z: np.where(z > 0, z, np.expm1(np.minimum(z, 0))),
           "tanh": np.tanh, "relu": lambda z: np.maximum(z, 0.0)}[actor.activation]
    x = obs.astype(np.float64)
    if actor.obs_mean is not None:
        x = (x - actor.obs_mean) / actor.obs_std
        x = x if actor.clip_obs is None else np.clip(x, -actor.clip_obs, actor.clip_obs)
    if actor.obs_index is not None:
        x = x[:, actor.obs_index]
    for k, layer in enumerate(actor.layers):
        x = x @ layer["w"] + layer["b"]
        if k < len(actor.layers) - 1:
            if actor.layer_norms:
                centred = x - x.mean(-1, keepdims=True)
                x = centred / np.sqrt(np.square(centred).mean(-1, keepdims=True) + actor.layer_norm_eps)
                x = x * actor.layer_norms[k]["w"] + actor.layer_norms[k]["b"]
            x = act(x)
    if actor.squash is not None:
        x = np.tanh(x) * actor.squash["scale"] + actor.squash["bias"]
    return x


@pytest.fixture(scope="module")
def holosoma_python() -> Path:
    return find_holosoma_python(REPO / ".venv-holosoma")


@pytest.mark.holosoma
@pytest.mark.parametrize("name", FASTSAC)
def test_shipped_fastsac_reads_into_its_architecture_and_acts_as_onnxruntime(name: str, holosoma_python: Path
                                                                             ) -> None:
    path = shipped_policy_path(name, holosoma_python)
    actor = read_actor(path, name)
    assert actor.architecture == "fastsac" and actor.describe()["architecture"] == "fastsac"
    assert (actor.input_name, actor.obs_dim, actor.action_dim) == ("actor_obs", 100, 29)
    assert actor.hidden_sizes == (512, 256, 128) and actor.activation == "silu"
    assert actor.obs_index is None  # its Slice takes all 100 entries, in order
    assert [norm["w"].shape for norm in actor.layer_norms] == [(512,), (256,), (128,)]
    assert actor.layer_norm_eps == pytest.approx(1e-5)
    inits = {i.name: numpy_helper.to_array(i) for i in onnx.load(str(path)).graph.initializer}
    np.testing.assert_array_equal(actor.squash["scale"], inits["actor.action_scale"])
    np.testing.assert_array_equal(actor.squash["bias"], inits["actor.action_bias"])
    np.testing.assert_array_equal(actor.obs_mean, inits["obs_normalizer._mean"].reshape(-1))
    assert actor.clip_obs is None and actor.metadata["kp"] and len(actor.metadata["dof_names"]) == 29
    obs = np.random.default_rng(0).normal(0.0, 1.0, size=(64, 100)).astype(np.float32)
    expected = onnxruntime_actions(path, obs)
    assert np.std(expected) > 0.5  # a policy that acts, not a near-zero output compared
    assert np.abs(numpy_actions(actor, obs) - expected).max() < 1e-4


@pytest.mark.holosoma
@pytest.mark.parametrize("name", ["holosoma:g1_29dof/ppo", "holosoma:t1_29dof/ppo"])
def test_shipped_ppo_walkers_read_as_plain_mlps(name: str, holosoma_python: Path) -> None:
    path = shipped_policy_path(name, holosoma_python)
    actor = read_actor(path, name)
    assert actor.architecture == "mlp" and actor.describe()["architecture"] == "mlp"
    assert (actor.layer_norms, actor.squash, actor.obs_index, actor.obs_mean) == ([], None, None, None)
    assert actor.hidden_sizes == (512, 256, 128) and actor.activation == "elu"
    obs = np.random.default_rng(1).normal(0.0, 1.0, size=(16, 100)).astype(np.float32)
    assert np.abs(numpy_actions(actor, obs) - onnxruntime_actions(path, obs)).max() < 1e-4


def _graph(tmp_path: Path, nodes: list, inits: dict[str, np.ndarray], width: int, out: int, opset: int) -> Path:
    graph = helper.make_graph(nodes, "actor", [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, width])],
                              [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, out])],
                              [numpy_helper.from_array(v, k) for k, v in inits.items()])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", opset)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    path = tmp_path / "actor.onnx"
    onnx.save(model, str(path))
    return path


def test_two_slices_a_layer_normalization_op_and_a_head_without_bias_read_the_same_way(tmp_path: Path) -> None:
    rng = np.random.default_rng(2)
    f32 = lambda *shape: rng.normal(0.0, 1.0, size=shape).astype(np.float32)
    i64 = lambda *v: np.asarray(v, np.int64)
    inits = {"s0": i64(0), "e0": i64(3), "s1": i64(5), "e1": i64(9), "ax": i64(-1), "w0": f32(7, 6), "b0": f32(6),
             "g0": f32(6), "h0": f32(6), "w1": f32(6, 4), "b1": f32(4), "scale": np.float32(0.5) + f32(4) ** 2}
    nodes = [helper.make_node("Slice", ["obs", "s0", "e0", "ax"], ["a"]),
             helper.make_node("Slice", ["obs", "s1", "e1", "ax"], ["c"]),
             helper.make_node("Concat", ["a", "c"], ["x"], axis=-1),
             helper.make_node("Gemm", ["x", "w0", "b0"], ["z0"]),
             helper.make_node("LayerNormalization", ["z0", "g0", "h0"], ["n0"], axis=-1, epsilon=1e-3),
             helper.make_node("Relu", ["n0"], ["r0"]),
             helper.make_node("MatMul", ["r0", "w1"], ["m1"]), helper.make_node("Add", ["m1", "b1"], ["z1"]),
             helper.make_node("Tanh", ["z1"], ["t"]), helper.make_node("Mul", ["t", "scale"], ["action"])]
    path = _graph(tmp_path, nodes, inits, 10, 4, 17)
    actor = read_actor(path)
    assert actor.architecture == "fastsac" and actor.obs_dim == 10 and actor.activation == "relu"
    np.testing.assert_array_equal(actor.obs_index, [0, 1, 2, 5, 6, 7, 8])
    assert actor.layer_norm_eps == pytest.approx(1e-3) and len(actor.layer_norms) == 1
    np.testing.assert_array_equal(actor.squash["bias"], np.zeros(4, np.float32))
    obs = rng.normal(0.0, 2.0, size=(8, 10)).astype(np.float32)
    assert np.abs(numpy_actions(actor, obs) - onnxruntime_actions(path, obs)).max() < 1e-5


@pytest.mark.holosoma
def test_an_op_no_actor_has_is_named_by_its_node(tmp_path: Path, holosoma_python: Path) -> None:
    """The shipped FastSAC file with a Softmax after its head: read up to there, refused naming the Softmax."""
    model = onnx.load(str(shipped_policy_path("holosoma:g1_29dof/fastsac", holosoma_python)))
    last = model.graph.node[-1]
    last.output[0] = "head"
    model.graph.node.append(helper.make_node("Softmax", ["head"], ["action"], name="/actor/mystery"))
    path = tmp_path / "odd.onnx"
    onnx.save(model, str(path))
    with pytest.raises(ConfigError) as info:
        read_actor(path, "odd-walker")
    text = str(info.value)
    assert "odd-walker" in text and "node /actor/mystery (Softmax)" in text and "FastSAC" in text
