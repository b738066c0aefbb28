"""YAML aliases at the edge: a few anchors load as written; an alias bomb, an alias nesting past the
depth limit and an alias inside its own anchor are ConfigErrors naming the file, found without writing
the aliases out (a count of the Python calls the refusal makes, not a time)."""

import sys

import pytest

from econmotor.config.loading import MAX_YAML_ALIAS_NODES, MAX_YAML_DEPTH, load_yaml_text, read_yaml
from econmotor.errors import ConfigError


def billion_laughs(levels: int = 9, width: int = 9) -> str:
    """The classic document: ``levels`` anchors, each a list of ``width`` aliases of the one before."""
    lines = [f"l0: &l0 [{', '.join(['lol'] * width)}]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * width)}]" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


def merge_key_bomb(levels: int = 9, width: int = 9) -> str:
    """The same growth through merge keys (``<<: [*m, *m, ...]``), which PyYAML flattens into lists of pairs."""
    lines = ["m0: &m0 {a: 1, b: 2, c: 3}"]
    lines += [f"m{i}: &m{i} {{<<: [{', '.join([f'*m{i - 1}'] * width)}], k{i}: 1}}" for i in range(1, levels)]
    return "\n".join(lines) + "\n"


def test_a_few_anchors_and_merge_keys_load_as_written():
    text = ("defaults: &defaults {lr: 0.001, gamma: 0.99}\n"
            "shared: &shared [1, 2, 3]\n"
            "a: {<<: *defaults, lr: 0.01}\n"
            "b: {ppo: *defaults, clips: *shared}\n")
    assert load_yaml_text(text, "x.yaml") == {
        "defaults": {"lr": 0.001, "gamma": 0.99}, "shared": [1, 2, 3],
        "a": {"lr": 0.01, "gamma": 0.99}, "b": {"ppo": {"lr": 0.001, "gamma": 0.99}, "clips": [1, 2, 3]}}


def test_aliases_up_to_the_limit_load():
    """An anchor of 100 values aliased 90 times adds 9,090 nodes: under the limit, loaded."""
    body = ", ".join(str(i) for i in range(100))
    text = f"base: &base [{body}]\n" + "".join(f"c{i}: *base\n" for i in range(90))
    data = load_yaml_text(text, "x.yaml")
    assert len(data) == 91 and data["c89"] == list(range(100))
    assert 90 * 101 < MAX_YAML_ALIAS_NODES


@pytest.mark.parametrize("text", [billion_laughs(), merge_key_bomb()], ids=["aliases", "merge-keys"])
def test_alias_bomb_is_refused_without_writing_it_out(tmp_path, text):
    """9^9 (387 million) values written out; the refusal walks the file's ~100 nodes: about 20,000 Python calls
    (parser and loader included), bounded here at 100,000, far below one call per written-out value."""
    path = tmp_path / "bomb.yaml"
    path.write_text(text)
    assert len(text) < 2_000
    calls = 0

    def count(frame, event, arg):
        nonlocal calls
        calls += event == "call"

    sys.setprofile(count)
    try:
        with pytest.raises(ConfigError) as info:
            read_yaml(path)
    finally:
        sys.setprofile(None)
    assert 0 < calls < 100_000
    assert str(path) in str(info.value) and "alias" in str(info.value)
    assert f"{MAX_YAML_ALIAS_NODES:,}" in str(info.value)


def test_alias_nesting_past_the_depth_limit_is_refused():
    """Each anchor one list deeper than the one before: few nodes, but nested past the limit."""
    text = "a0: &a0 [x]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, MAX_YAML_DEPTH + 5))
    with pytest.raises(ConfigError, match=f"more than {MAX_YAML_DEPTH} levels deep"):
        load_yaml_text(text, "deep.yaml")


@pytest.mark.parametrize("text", ["a: &x [1, *x]\n", "a: &x {k: *x}\n", "a: &x {<<: *x}\n"],
                         ids=["list", "mapping", "merge"])
def test_alias_inside_its_own_anchor_is_refused(text):
    with pytest.raises(ConfigError, match="refers to the anchor that contains it") as info:
        load_yaml_text(text, "loop.yaml")
    assert "loop.yaml" in str(info.value)


def test_undefined_alias_is_a_config_error():
    with pytest.raises(ConfigError, match="undefined alias"):
        load_yaml_text("a: *nowhere\n", "x.yaml")
