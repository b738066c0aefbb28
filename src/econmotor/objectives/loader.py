"""load_objective_spec: read an objective YAML in one of three forms.

1. Flat weights (the spec's example)::

       mpl_weight: 1.0
       energy_weight: 0.2
       error_weight: 0.5
       novelty_weight: 0.0
       risk_weight: 0.3
       extra_weights: {stability_margin: -0.1}

2. An objective vector ``[mpl, error, energy, safety, novelty]``::

       objective_vector: [2.0, 1.0, 0.5, 1.0, 0.0]

3. A preset (``throughput``, ``safety``, ``energy_saver``, ``balanced``,
   ``throughput_focused``, ``premium_safety``)::

       objective_preset: throughput

Forms 2 and 3 map the vector onto the spec as mpl_weight=w_mpl,
error_weight=w_error, energy_weight=w_energy, risk_weight=w_safety,
novelty_weight=w_novelty. An optional ``name`` labels the objective in every form,
``extra_weights`` may accompany any form, and so may ``energy_term`` (``wh``, the default, or
``usd``: how J counts energy, :mod:`econmotor.config.objective_profile`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from econmotor.config.loading import as_float, as_str, check_keys, path_name, read_yaml_mapping, require_mapping
from econmotor.config.objective_profile import ENERGY_TERMS, OBJECTIVE_PRESETS, ObjectiveVector
from econmotor.errors import ConfigError
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.valuation.reward_builder import combine_terms, energy_price_of, episode_j, reward_terms_from_metrics

_FLAT_KEYS = ("mpl_weight", "energy_weight", "error_weight", "novelty_weight", "risk_weight")
_ALL_KEYS = (*_FLAT_KEYS, "extra_weights", "objective_vector", "objective_preset", "name", "energy_term")


def objective_from_vector(vector: ObjectiveVector, name: str = "objective",
                          extra_weights: dict[str, float] | None = None) -> EconomicObjectiveSpec:
    """Map ``[mpl, error, energy, safety, novelty]`` weights (and the vector's energy term) onto an
    EconomicObjectiveSpec."""
    return EconomicObjectiveSpec(
        mpl_weight=vector.w_mpl,
        error_weight=vector.w_error,
        energy_weight=vector.w_energy,
        risk_weight=vector.w_safety,
        novelty_weight=vector.w_novelty,
        extra_weights=extra_weights or {},
        name=name,
        energy_term=vector.energy_term,
    )


def objective_weights_vector(spec: EconomicObjectiveSpec) -> list[float]:
    """The ``[mpl, error, energy, safety, novelty]`` weights of a spec (inverse of :func:`objective_from_vector`).

    Penalty weights enter as magnitudes (the overlay uses ``-|w|`` for them), so a spec
    built from a vector gives that vector back; the RewardBuilder J of a run trained under
    ``spec`` is ``episode_j(summary, objective_weights_vector(spec), economics)``.
    """
    return [spec.mpl_weight, abs(spec.error_weight), abs(spec.energy_weight), abs(spec.risk_weight),
            spec.novelty_weight]


def objective_j(spec: EconomicObjectiveSpec, summary: Any, economics: Any) -> float:
    """An episode's J under ``spec``: :func:`econmotor.valuation.episode_j` of its weights
    (:func:`objective_weights_vector`) with its own energy term (``spec.energy_term``; ``"usd"`` reads
    ``economics``' electricity price). The J a report prints and held-out selection keeps a checkpoint by."""
    return episode_j(summary, objective_weights_vector(spec), economics, spec.energy_term)


def running_objective_j(spec: EconomicObjectiveSpec, economics: Any, *, units: Any, errors: Any, energy_wh: Any,
                        length_s: Any, fell: Any) -> Any:
    """The J an episode would report if it ended now: :func:`objective_j`'s formula on a meter's running
    sums, over NumPy arrays of episodes (or floats).

    ``mpl = units * 3600 / length_s`` (0 before any time has passed), ``error_rate = errors / (units +
    errors)`` (0 before anything was attempted), ``energy_wh`` as metered, a fall catastrophic, no novelty:
    the summary the meter makes of the episode's raw metrics. Its increments, summed over an episode's
    steps from ``J = 0`` at the start, are that episode's J (a learner paid them is paid what selection and
    the report score); rates use the episode's own length and legs, not an assumed one.
    """
    units, errors, length_s = (np.asarray(v, dtype=float) for v in (units, errors, length_s))
    attempted = units + errors
    mpl = np.where(length_s > 0, units * 3600.0 / np.where(length_s > 0, length_s, 1.0), 0.0)
    error_rate = np.where(attempted > 0, errors / np.where(attempted > 0, attempted, 1.0), 0.0)
    terms = reward_terms_from_metrics(mpl, error_rate, np.asarray(energy_wh, dtype=float),
                                      np.asarray(fell, dtype=bool), 0.0, energy_term=spec.energy_term,
                                      energy_price_usd_per_kwh=energy_price_of(economics))
    return combine_terms(objective_weights_vector(spec), terms)


def parse_objective_spec(data: Any, source: str | Path = "<objective>") -> EconomicObjectiveSpec:
    """Validate an already-parsed mapping (any of the three forms)."""
    data = require_mapping(data, source, None)
    check_keys(data, _ALL_KEYS, source)
    forms = [k for k in ("objective_vector", "objective_preset") if k in data]
    if any(k in data for k in _FLAT_KEYS):
        forms.append("flat weights")
    if len(forms) > 1:
        raise ConfigError(source, None, f"give exactly one objective form, got {forms}",
                          "flat *_weight keys | objective_vector | objective_preset")
    name = path_name(data.get("name", Path(str(source)).stem if source != "<objective>" else "objective"),
                     source, "name")
    extras_raw = require_mapping(data["extra_weights"], source, "extra_weights") if "extra_weights" in data else {}
    extras = {k: as_float(v, source, f"extra_weights.{k}") for k, v in extras_raw.items()}
    for k in extras:
        if k in ("mpl_per_hour", "energy_kwh", "error_rate", "novelty_score", "risk_score"):
            raise ConfigError(source, f"extra_weights.{k}", "this metric has its own *_weight key")
    energy_term = as_str(data.get("energy_term", "wh"), source, "energy_term", ENERGY_TERMS)
    if "objective_vector" in data:
        vector = ObjectiveVector.from_list(data["objective_vector"], str(source), energy_term)
        return objective_from_vector(vector, name, extras)
    if "objective_preset" in data:
        preset = as_str(data["objective_preset"], source, "objective_preset", OBJECTIVE_PRESETS)
        return objective_from_vector(ObjectiveVector.from_preset(preset, energy_term),
                                     name if "name" in data else preset, extras)
    if not forms:
        raise ConfigError(source, None, "no objective given",
                          "flat *_weight keys | objective_vector | objective_preset")
    weights = {k: as_float(data[k], source, k) for k in _FLAT_KEYS if k in data}
    if not any(weights.values()) and not any(extras.values()) and "mpl_weight" in weights:
        raise ConfigError(source, None, "every weight is zero: the objective values nothing",
                          "at least one non-zero *_weight")
    return EconomicObjectiveSpec(**weights, extra_weights=extras, name=name, energy_term=energy_term)


def load_objective_spec(path: str | Path) -> EconomicObjectiveSpec:
    """Load an objective YAML file (see the module docstring for the three forms)."""
    return parse_objective_spec(read_yaml_mapping(path), path)
