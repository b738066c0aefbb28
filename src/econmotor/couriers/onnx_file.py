"""Reading an ONNX file a user names: the one place a policy file is parsed.

Every reader of a policy file (the actor an ``--init-policy`` starts from, the contract a ``--policy`` is
priced by, the onnxruntime handle of a deployed policy) opens it here, so a file that is not an ONNX model
(truncated, corrupt, another format renamed) is one :class:`~econmotor.errors.ConfigError` naming the file,
and the command line exits 2, instead of protobuf's ``DecodeError`` or onnxruntime's ``InvalidProtobuf``
escaping as a traceback. Imports only onnx / onnxruntime (in the function that needs it): it also runs in
.venv-holosoma.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from econmotor.errors import ConfigError

#: what a policy file must be, in the error's "allowed" part
ONNX_ALLOWED = "an ONNX model file (an exported policy, e.g. Holosoma's or econmotor's policy.onnx)"


def _unreadable(path: str | Path, source: str | None, why: object) -> ConfigError:
    """The error of a file that is not an ONNX model: names the file (and what the user called it)."""
    named = str(path) if source in (None, str(path)) else f"{source} ({path})"
    first_line = str(why).strip().splitlines()[0] if str(why).strip() else type(why).__name__
    return ConfigError(named, None, f"not a readable ONNX model: {first_line}", ONNX_ALLOWED)


def load_onnx(path: str | Path, source: str | None = None, *, load_external_data: bool = True) -> Any:
    """The ``onnx.ModelProto`` of ``path``; a ConfigError naming the file (and ``source``, what the user
    named it) when the bytes are not an ONNX model or hold no graph."""
    import onnx
    from google.protobuf.message import DecodeError

    try:
        model = onnx.load(str(path), load_external_data=load_external_data)
    except (DecodeError, ValueError, OSError) as exc:  # protobuf's wire errors; onnx's own format checks
        raise _unreadable(path, source, exc) from exc
    if not model.graph.node and not model.graph.input:  # protobuf reads an empty or zeroed file as an empty model
        raise _unreadable(path, source, "the file holds no graph")
    return model


def onnx_session(model: str | Path | bytes, source: str | Path, options: Any = None) -> Any:
    """An onnxruntime CPU session of ``model`` (a path, or a serialised model); onnxruntime's refusal of
    the file (not a model, a graph it cannot run) is a ConfigError naming ``source``."""
    import onnxruntime as ort

    try:
        return ort.InferenceSession(model if isinstance(model, bytes) else str(model), options,
                                    providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime's errors share no base class but their module
        if not type(exc).__module__.startswith("onnxruntime"):
            raise
        raise _unreadable(source, None, exc) from exc
