"""Reading and validating YAML configs at the edge.

Every loader in econmotor goes through these helpers, so every bad input
raises :class:`econmotor.errors.ConfigError` naming the file, the key and what
is allowed: unknown keys (with a did-you-mean), wrong types, NaN/inf, negative
prices, empty or non-mapping files. YAML is read by one bounded loader
(:func:`load_yaml_text`): at most :data:`MAX_YAML_BYTES` bytes, nesting at most
:data:`MAX_YAML_DEPTH` deep (checked on the event stream, before anything recursive
runs), duplicate keys rejected, and aliases bounded: written out, the aliases (``*name``,
``<<: *name``) may add at most :data:`MAX_YAML_ALIAS_NODES` nodes and no nesting beyond
:data:`MAX_YAML_DEPTH`, and may not refer to a node that contains them. So a "billion
laughs" document (2 KB on disk, 10^9 strings once expanded) is refused in milliseconds,
before any code walks what it would expand to. Every name that becomes part of a file path (objective
names, task ids, datapack ids, run names) goes through :func:`path_name`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from econmotor.errors import ConfigError, did_you_mean

#: Largest YAML file any loader reads (configs are a few KB).
MAX_YAML_BYTES = 1 << 20
#: Deepest nesting of mappings and lists a YAML config may have.
MAX_YAML_DEPTH = 32
#: Most nodes that aliases may add to a YAML config when written out (configs reuse a few
#: anchors: the shipped catalog adds a few hundred).
MAX_YAML_ALIAS_NODES = 10_000
#: Longest name that may become a file or directory name.
MAX_NAME_LENGTH = 120


class _UniqueKeyLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that rejects a key given twice in one mapping."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":  # ``<<: *anchor``: merged keys may be overridden
                continue
            key = self.construct_object(key_node, deep=deep)
            try:
                duplicate = key in seen
                seen.add(key)
            except TypeError:  # unhashable key: SafeLoader reports it below
                continue
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark)  # the mark says where
        return super().construct_mapping(node, deep=deep)


_UniqueKeyLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _UniqueKeyLoader.construct_mapping)


def load_yaml_text(text: str | bytes, source: str | Path) -> Any:
    """Parse YAML with the size, depth and duplicate-key limits (module docstring)."""
    size = len(text.encode("utf-8") if isinstance(text, str) else text)
    if size > MAX_YAML_BYTES:
        raise ConfigError(source, None, f"file is {size:,} bytes, more than the limit of {MAX_YAML_BYTES:,}")
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ConfigError(source, None, f"not UTF-8 text: {exc.reason} at byte {exc.start}") from None
    _check_flow_depth(text, source)
    try:
        depth = 0
        nodes = 0
        for event in yaml.parse(text, Loader=yaml.SafeLoader):  # iterative: no recursion on deep input
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                depth += 1
                if depth > MAX_YAML_DEPTH:
                    line = event.start_mark.line + 1 if event.start_mark else "?"
                    raise ConfigError(source, None, f"nested more than {MAX_YAML_DEPTH} levels deep (line {line})")
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                depth -= 1
            if isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent, yaml.ScalarEvent)):
                nodes += 1
        loader = _UniqueKeyLoader(text)
        try:
            root = loader.get_single_node()  # the node graph: an alias is a second edge to its anchor's node
            if root is None:
                return None
            _check_aliases(root, nodes, source)
            return loader.construct_document(root)
        finally:
            loader.dispose()
    except yaml.YAMLError as exc:
        raise ConfigError(source, None, f"not valid YAML: {_yaml_problem(exc)}") from None
    except RecursionError:  # belt and braces: the depth scan above should make this unreachable
        raise ConfigError(source, None, f"nested too deeply (limit {MAX_YAML_DEPTH})") from None


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """PyYAML's complaint, where it is (line and column, 1-based), without its ``in "<unicode string>"``
    (the text was parsed from memory; the ConfigError names the file)."""
    if isinstance(exc, yaml.MarkedYAMLError) and exc.problem:
        mark = exc.problem_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        return " ".join(f"{exc.context + ': ' if exc.context else ''}{exc.problem}{where}".split())
    return " ".join(str(exc).split())


def _node_children(node: yaml.Node) -> list[yaml.Node]:
    if isinstance(node, yaml.MappingNode):
        return [n for pair in node.value for n in pair]
    if isinstance(node, yaml.SequenceNode):
        return list(node.value)
    return []


def _check_aliases(root: yaml.Node, distinct_nodes: int, source: str | Path) -> None:
    """Refuse aliases that expand past :data:`MAX_YAML_ALIAS_NODES` extra nodes, nest past
    :data:`MAX_YAML_DEPTH` or form a cycle, on the composed graph before anything is constructed.

    One iterative post-order walk with each node's written-out size and depth memoised (linear
    in the file, whatever the expansion). Sizes saturate at the limit, so numbers stay small.
    """
    cap = distinct_nodes + MAX_YAML_ALIAS_NODES
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    open_nodes: set[int] = set()  # entered, children not finished: the current node's ancestors
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, children_done = stack.pop()
        nid = id(node)
        children = _node_children(node)
        if children_done:
            open_nodes.discard(nid)
            size[nid] = min(cap + 1, 1 + sum(size[id(c)] for c in children))
            depth[nid] = 1 + max((depth[id(c)] for c in children), default=0) if children else 0
            line = node.start_mark.line + 1 if node.start_mark else "?"
            if size[nid] > cap:
                raise ConfigError(source, None, f"aliases (*name) expand to more than {MAX_YAML_ALIAS_NODES:,} "
                                  f"extra values when written out (line {line}); a config reuses a few "
                                  "anchors, not an alias bomb: write the values out")
            if depth[nid] > MAX_YAML_DEPTH:
                raise ConfigError(source, None, f"aliases (*name) nest the values more than {MAX_YAML_DEPTH} "
                                  f"levels deep (line {line})")
            continue
        if nid in size:
            continue
        open_nodes.add(nid)
        stack.append((node, True))
        for child in children:
            if id(child) in open_nodes:
                line = child.start_mark.line + 1 if child.start_mark else "?"
                raise ConfigError(source, None, f"an alias refers to the anchor that contains it (anchor at "
                                  f"line {line}): the value would be infinite")
            if id(child) not in size:
                stack.append((child, False))


def _check_flow_depth(text: str, source: str | Path) -> None:
    """Refuse ``[[[[...`` / ``{{{{...`` nesting before PyYAML's scanner, which is quadratic in it.

    Counts brackets outside quotes and comments (a conservative over-count is fine: real
    configs nest a few levels)."""
    depth = 0
    quote = ""
    comment = False
    for ch in text:
        if comment:
            comment = ch != "\n"
        elif quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#":
            comment = True
        elif ch in "[{":
            depth += 1
            if depth > MAX_YAML_DEPTH:
                raise ConfigError(source, None, f"nested more than {MAX_YAML_DEPTH} levels deep")
        elif ch in "]}":
            depth = max(0, depth - 1)


def read_yaml(path: str | Path) -> Any:
    """Read any YAML file through :func:`load_yaml_text` (missing, unreadable or binary: ConfigError)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(path, None, "is a directory; expected a YAML file")
    if not path.is_file():
        raise ConfigError(path, None, "file not found")
    try:
        size = path.stat().st_size
        if size > MAX_YAML_BYTES:
            raise ConfigError(path, None, f"file is {size:,} bytes, more than the limit of {MAX_YAML_BYTES:,}")
        data = path.read_bytes()
    except OSError as exc:
        raise ConfigError(path, None, f"cannot read: {exc.strerror or exc}") from None
    return load_yaml_text(data, path)


def read_yaml_mapping(path: str | Path) -> dict[str, Any]:
    """Read a YAML file whose top level must be a non-empty mapping with string keys."""
    return require_mapping(read_yaml(path), Path(path), None)


def path_name(value: Any, source: str | Path, key: str | None) -> str:
    """``value`` if it is safe as one file or directory name, else a ConfigError.

    The one check every name that becomes part of a path goes through (objective names,
    task ids, datapack ids, run names): no ``/`` or ``\\``, not ``.``/``..`` or hidden
    (leading ``.``), no control characters, 1..MAX_NAME_LENGTH characters. So
    ``base / name`` always stays directly inside ``base``.
    """
    if not isinstance(value, str):
        raise ConfigError(source, key, f"expected a string, got {type(value).__name__} {value!r}")
    allowed = f"1-{MAX_NAME_LENGTH} characters, no '/', '\\', leading '.' or control characters"
    if not value or len(value) > MAX_NAME_LENGTH:
        raise ConfigError(source, key, f"name of {len(value)} characters; it becomes a file name", allowed)
    if "/" in value or "\\" in value or value.startswith(".") or any(ord(c) < 32 or ord(c) == 127 for c in value):
        raise ConfigError(source, key, f"{value!r} cannot be used as a file name (it would leave the output "
                          "directory or hide the file)", allowed)
    return value


def require_mapping(data: Any, source: str | Path, key: str | None) -> dict[str, Any]:
    """Check that ``data`` is a non-empty mapping with string keys and return it as a dict."""
    if data is None:
        raise ConfigError(source, key, "is empty; expected a mapping of keys to values")
    if not isinstance(data, Mapping):
        raise ConfigError(source, key, f"expected a mapping, got {type(data).__name__}")
    for k in data:
        if not isinstance(k, str):
            raise ConfigError(source, join_key(key, str(k)), "keys must be strings")
    return dict(data)


def join_key(prefix: str | None, key: str) -> str:
    return f"{prefix}.{key}" if prefix else key


def check_keys(
    data: Mapping[str, Any],
    allowed: Iterable[str],
    source: str | Path,
    prefix: str | None = None,
    required: Iterable[str] = (),
) -> None:
    """Reject keys not in ``allowed`` (with a did-you-mean) and missing ``required`` keys."""
    allowed = list(allowed)
    for k in data:
        if k not in allowed:
            raise ConfigError(
                source, join_key(prefix, k), "unknown key" + did_you_mean(k, allowed), allowed
            )
    for k in required:
        if k not in data:
            raise ConfigError(source, join_key(prefix, k), "missing required key", allowed)


def as_float(
    value: Any,
    source: str | Path,
    key: str,
    *,
    min_value: float | None = None,
    max_value: float | None = None,
    allow_negative: bool = True,
) -> float:
    """Validate a finite real number (bools are rejected) within optional bounds."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(source, key, f"expected a number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(source, key, f"must be finite, got {value}")
    if not allow_negative and value < 0:
        raise ConfigError(source, key, f"must not be negative, got {value}", ">= 0")
    if min_value is not None and value < min_value:
        raise ConfigError(source, key, f"must be >= {min_value}, got {value}")
    if max_value is not None and value > max_value:
        raise ConfigError(source, key, f"must be <= {max_value}, got {value}")
    return value


def as_int(value: Any, source: str | Path, key: str, *, min_value: int | None = None) -> int:
    """Validate an integer (bools and non-integral floats are rejected)."""
    if isinstance(value, bool):
        raise ConfigError(source, key, f"expected an integer, got {value!r}")
    if isinstance(value, float) and value.is_integer():
        value = int(value)
    if not isinstance(value, int):
        raise ConfigError(source, key, f"expected an integer, got {type(value).__name__} {value!r}")
    if min_value is not None and value < min_value:
        raise ConfigError(source, key, f"must be >= {min_value}, got {value}")
    return value


def as_str(value: Any, source: str | Path, key: str, allowed: Iterable[str] | None = None) -> str:
    """Validate a string, optionally one of ``allowed``."""
    if not isinstance(value, str):
        raise ConfigError(source, key, f"expected a string, got {type(value).__name__} {value!r}")
    if allowed is not None:
        allowed = list(allowed)
        if value not in allowed:
            raise ConfigError(source, key, f"'{value}' is not allowed" + did_you_mean(value, allowed), allowed)
    return value


def as_range(
    value: Any,
    source: str | Path,
    key: str,
    *,
    min_value: float | None = None,
    max_value: float | None = None,
) -> tuple[float, float]:
    """Validate ``[low, high]`` with ``low <= high``, both finite and within bounds."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(source, key, f"expected a [low, high] pair, got {value!r}")
    low = as_float(value[0], source, key, min_value=min_value, max_value=max_value)
    high = as_float(value[1], source, key, min_value=min_value, max_value=max_value)
    if low > high:
        raise ConfigError(source, key, f"low {low} is greater than high {high}")
    return (low, high)
