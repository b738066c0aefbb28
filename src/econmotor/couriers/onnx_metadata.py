"""econmotor's metadata in an exported policy's ONNX file: the format every reader and writer shares.

Two layouts: econmotor's own (the couriers' ``policy.onnx``), one ``econmotor`` entry holding JSON (task id,
compiled overlay, datapack ids, economic assumptions, observation / action layout); and Holosoma's (its
runs and imports, the card robots' exports), Holosoma's own entries (``dof_names``, ``kp``, ...) each
JSON-encoded, with econmotor's facts beside them as ``econmotor_<key>`` entries. Written by
:mod:`econmotor.couriers.onnx_export`, read by :mod:`econmotor.couriers.onnx_actor` and the deployed
handle (``motor_backend/onnx_policy.py``).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

#: the ONNX ``metadata_props`` key of the JSON metadata.
METADATA_KEY = "econmotor"
#: in Holosoma-format files, econmotor's metadata entries are ``econmotor_<key>`` (JSON values)
ECONMOTOR_PREFIX = "econmotor_"


def json_or_text(value: str) -> Any:
    """A metadata value decoded from JSON, or the text itself when it is not JSON."""
    try:
        return json.loads(value)
    except (json.JSONDecodeError, TypeError):
        return value


def econmotor_metadata(entries: Mapping[str, str]) -> dict[str, Any]:
    """econmotor's metadata of an ONNX file's entries: the ``econmotor`` entry, else the ``econmotor_<key>`` ones."""
    if METADATA_KEY in entries:
        return json.loads(entries[METADATA_KEY])
    return {k[len(ECONMOTOR_PREFIX):]: json_or_text(v) for k, v in entries.items() if k.startswith(ECONMOTOR_PREFIX)}
