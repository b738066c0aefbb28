"""Pareto filtering and exact hypervolume on hand-computed cases."""

from itertools import combinations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from econmotor.analysis.pareto import (
    PARETO_CRITERIA,
    default_reference_point,
    hypervolume,
    pareto_front,
    pareto_mask,
)
from econmotor.errors import ConfigError


def test_pareto_mask_drops_dominated_points_and_keeps_duplicates():
    pts = np.array([[1, 3], [2, 2], [3, 1], [2, 3], [3, 3], [1, 3]], float)  # minimise both
    assert pareto_mask(pts).tolist() == [True, True, True, False, False, True]


def test_a_point_equal_in_all_but_one_coordinate_is_dominated():
    pts = np.array([[1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.5]])
    assert pareto_mask(pts).tolist() == [True, False]


def test_hypervolume_2d_staircase_by_hand():
    # points (1,3), (2,2), (3,1) against (4,4): 3 + 2 + 1 unit-wide columns of heights 1, 2, 3 -> 6
    assert hypervolume(np.array([[1, 3], [2, 2], [3, 1]], float), [4, 4]) == pytest.approx(6.0)


def test_hypervolume_3d_two_boxes_by_inclusion_exclusion():
    # box A = [0,2]x[0,1]x[0,1] (vol 2), box B = [0,1]x[0,2]x[0,1] (vol 2), overlap [0,1]^3 (vol 1)
    pts = np.array([[0, 1, 1], [1, 0, 1]], float)
    assert hypervolume(pts, [2, 2, 2]) == pytest.approx(3.0)


def test_hypervolume_ignores_points_outside_the_reference_box():
    pts = np.array([[1, 1, 1, 1], [5, 0, 0, 0]], float)
    assert hypervolume(pts, [2, 2, 2, 2]) == pytest.approx(1.0)
    assert hypervolume(np.zeros((0, 4)), [1, 1, 1, 1]) == 0.0


def _inclusion_exclusion(pts: np.ndarray, ref: np.ndarray) -> float:
    total = 0.0
    for size in range(1, len(pts) + 1):
        for subset in combinations(range(len(pts)), size):
            corner = pts[list(subset)].max(axis=0)
            total += (-1) ** (size + 1) * np.prod(np.clip(ref - corner, 0, None))
    return total


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(*[st.integers(0, 9)] * 4), min_size=1, max_size=7))
def test_hypervolume_4d_matches_inclusion_exclusion(points):
    pts = np.array(points, float)
    ref = np.full(4, 10.0)
    assert hypervolume(pts, ref) == pytest.approx(_inclusion_exclusion(pts, ref))


def test_pareto_front_of_runs_maximises_mpl_and_minimises_the_rest():
    #                  MPL, Wh/unit, error, risk
    runs = np.array([[60.0, 2.0, 0.05, 0.1],    # best MPL
                     [40.0, 1.0, 0.05, 0.1],    # best energy
                     [50.0, 2.5, 0.10, 0.2],    # dominated by run 0
                     [30.0, 3.0, 0.01, 0.1]])   # best error
    front = pareto_front(runs, {"energy_wh_per_unit": 4.0})
    assert front.indices == (0, 1, 3)
    assert front.reference_point == {"mpl_units_per_hour": 0.0, "energy_wh_per_unit": 4.0,
                                      "error_rate": 1.0, "risk_score": 1.0}
    assert front.hypervolume == pytest.approx(
        _inclusion_exclusion(np.array([[-60, 2, .05, .1], [-40, 1, .05, .1], [-30, 3, .01, .1]]),
                             np.array([0, 4, 1, 1.0])))
    assert front.to_dict()["criteria"] == {c: ("max" if c == "mpl_units_per_hour" else "min")
                                           for c in PARETO_CRITERIA}


def test_default_reference_point_bounds_every_finite_run():
    runs = np.array([[10.0, 2.0, 0.1, 0.0], [20.0, np.inf, 0.2, 3.0]])
    ref = default_reference_point(runs)
    assert ref == {"mpl_units_per_hour": 0.0, "energy_wh_per_unit": pytest.approx(2.2),
                   "error_rate": 1.0, "risk_score": 3.0}


def test_unknown_reference_criterion_is_a_config_error():
    with pytest.raises(ConfigError, match="reference_point.speed"):
        pareto_front(np.ones((1, 4)), {"speed": 1.0})


def _inclusion_exclusion(pts: np.ndarray, ref: np.ndarray) -> float:
    """Union of boxes [p, ref] by inclusion-exclusion over all subsets (exact, small n)."""
    from itertools import combinations

    total = 0.0
    for k in range(1, len(pts) + 1):
        for subset in combinations(range(len(pts)), k):
            corner = pts[list(subset)].max(axis=0)
            total += (-1) ** (k + 1) * float(np.prod(np.clip(ref - corner, 0, None)))
    return total


@pytest.mark.parametrize("d", [3, 4, 5])
def test_hypervolume_matches_inclusion_exclusion_on_random_sets(d):
    rng = np.random.default_rng(d)
    for trial in range(40):
        n = int(rng.integers(1, 8))
        pts = rng.integers(0, 4, size=(n, d)).astype(float) if trial % 2 else rng.random((n, d)) * 3
        ref = np.full(d, 4.0)
        assert hypervolume(pts, ref) == pytest.approx(_inclusion_exclusion(pts, ref), rel=1e-9, abs=1e-12)


# ---------------------------------------------------------------- what mutation testing found unchecked
def _config_error(call) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        call()
    return info.value


def test_bad_shapes_and_references_name_the_source_the_key_and_the_problem():
    err = _config_error(lambda: pareto_mask(np.ones(3)))
    assert (err.source, err.key, err.detail) == ("<pareto>", None, "expected an (n, d) array, got shape (3,)")
    err = _config_error(lambda: hypervolume(np.ones((2, 3)), [1.0, 1.0]))
    assert (err.source, err.key, err.detail) == ("<pareto>", "reference",
                                                 "points (2, 3) and reference (2,) disagree")
    err = _config_error(lambda: hypervolume(np.ones(3), [1.0, 1.0, 1.0]))
    assert (err.source, err.key) == ("<pareto>", "reference") and "points (3,)" in err.detail
    err = _config_error(lambda: hypervolume(np.ones((1, 2)), [1.0, np.inf]))
    assert (err.source, err.key, err.detail) == ("<pareto>", "reference",
                                                 "reference point must be finite, got [1.0, inf]")
    err = _config_error(lambda: pareto_front(np.ones((1, 4)), {"speed": 1.0}))
    assert (err.source, err.key, err.detail) == ("<pareto>", "reference_point.speed", "unknown criterion")
    assert err.allowed == ", ".join(sorted(PARETO_CRITERIA))


def test_an_empty_set_has_an_empty_mask_and_no_volume():
    mask = pareto_mask(np.zeros((0, 4)))
    assert mask.shape == (0,) and mask.dtype == bool
    assert hypervolume(np.zeros((0, 2)), [1.0, 1.0]) == 0.0


def test_a_point_on_the_reference_boundary_adds_nothing():
    assert hypervolume(np.array([[1.0, 2.0], [0.0, 1.0]]), [2.0, 2.0]) == pytest.approx(2.0)
    assert hypervolume(np.array([[2.0, 0.0]]), [2.0, 2.0]) == 0.0


@pytest.mark.parametrize("d", [1, 2])
def test_low_dimensional_hypervolume_matches_inclusion_exclusion(d):
    rng = np.random.default_rng(10 + d)
    for _ in range(20):
        pts = rng.random((int(rng.integers(1, 6)), d)) * 3
        ref = np.full(d, 4.0) + np.arange(d)  # unequal bounds: each axis uses its own
        assert hypervolume(pts, ref) == pytest.approx(_inclusion_exclusion(pts, ref), rel=1e-12)
    assert hypervolume(np.array([[1.0], [3.0]]), [5.0]) == pytest.approx(4.0)
    assert hypervolume(np.array([[1.0, 3.0], [2.0, 1.0]]), [4.0, 5.0]) == pytest.approx(3 * 2 + 2 * 2)


@pytest.mark.parametrize("d", [3, 4, 5])
def test_hypervolume_with_unequal_reference_bounds_matches_inclusion_exclusion(d):
    rng = np.random.default_rng(20 + d)
    ref = 4.0 + np.arange(d, dtype=float)  # a slab or a face read against the wrong bound would show
    for _ in range(25):
        pts = rng.random((int(rng.integers(1, 7)), d)) * 4
        assert hypervolume(pts, ref) == pytest.approx(_inclusion_exclusion(pts, ref), rel=1e-9, abs=1e-12)


def test_default_reference_point_without_runs_or_with_no_positive_energy():
    assert default_reference_point(np.zeros((0, 4))) == {"mpl_units_per_hour": 0.0, "energy_wh_per_unit": 1.0,
                                                         "error_rate": 1.0, "risk_score": 1.0}
    runs = np.array([[10.0, 0.0, 0.1, 0.5], [20.0, np.inf, 0.2, 0.2]])
    assert default_reference_point(runs) == {"mpl_units_per_hour": 0.0, "energy_wh_per_unit": 1.0,
                                             "error_rate": 1.0, "risk_score": 1.0}
    assert default_reference_point(np.array([[10.0, 0.5, 0.1, 0.2]]))["energy_wh_per_unit"] == pytest.approx(0.55)


def test_pareto_front_to_dict_says_every_field():
    front = pareto_front(np.array([[60.0, 2.0, 0.05, 0.1], [50.0, 2.5, 0.1, 0.2]]))
    assert front.to_dict() == {
        "criteria": {"mpl_units_per_hour": "max", "energy_wh_per_unit": "min", "error_rate": "min",
                     "risk_score": "min"},
        "indices": [0], "reference_point": front.reference_point, "hypervolume": front.hypervolume,
        "hypervolume_method": "exact, hypervolume by slicing objectives (HSO)"}
    assert front.hypervolume == pytest.approx(60.0 * (1.1 * 2.5 - 2.0) * 0.95 * 0.9)


def test_a_run_with_a_missing_figure_is_never_on_the_front_unless_alone_in_it():
    runs = np.array([[60.0, np.nan, 0.05, 0.1], [50.0, 2.0, 0.1, 0.2]])
    front = pareto_front(runs)
    assert front.indices == (0, 1)  # NaN energy counts as the worst energy: 0 still wins on MPL and error
    assert front.hypervolume == pytest.approx(50.0 * (1.1 * 2.0 - 2.0) * 0.9 * 0.8)


def test_a_missing_figure_counts_as_the_worst_so_a_run_better_elsewhere_dominates_it():
    runs = np.array([[50.0, np.nan, 0.1, 0.2], [60.0, 2.0, 0.05, 0.1]])
    assert pareto_front(runs).indices == (1,)  # NaN compared as-is would dominate nothing and be dominated by none
