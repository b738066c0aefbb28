"""The objective-surface solver on small hand-computed episode sets."""

import numpy as np
import pytest

from econmotor.analysis.episode_table import EpisodeTable, RunInfo
from econmotor.analysis.objective_surface import (
    Objective,
    preset_objectives,
    reward_term_matrix,
    simplex_grid,
    solve_objective_surface,
)
from econmotor.analysis.surface_report import surface_cells, surface_document, surface_markdown
from econmotor.config.objective_profile import ObjectiveVector
from econmotor.config.task_economics import TaskEconomics
from econmotor.valuation import ConstraintSet, build_reward_terms, combine_reward, episode_j
from econmotor.valuation.reward_builder import REWARD_TERM_NAMES


def three_runs() -> EpisodeTable:
    """Run 'fast': high MPL, many errors; 'careful': low MPL, few errors; 'frugal': low energy.

    Episodes are given interleaved to check that the table groups them by run.
    """
    runs = [RunInfo("fast", datapacks=("dp_a",)), RunInfo("careful", datapacks=("dp_b",)),
            RunInfo("frugal", datapacks=("dp_a", "dp_b"))]
    #            fast  careful frugal fast  careful frugal
    run_index = [0,    1,      2,     0,    1,      2]
    return EpisodeTable.from_arrays(
        runs, np.array(run_index),
        mpl_units_per_hour=np.array([100.0, 40.0, 50.0, 80.0, 44.0, 50.0]),
        error_rate=np.array([0.20, 0.01, 0.03, 0.10, 0.03, 0.05]),
        energy_wh=np.array([30.0, 20.0, 5.0, 30.0, 20.0, 5.0]),
        energy_wh_per_unit=np.array([3.0, 2.0, 0.5, 3.0, 2.0, 0.5]),
        wage_parity=np.array([1.2, 0.6, 0.8, 1.0, 0.7, 1.0]),
        catastrophic=np.array([True, False, False, False, False, False]),
        energy_price_usd_per_kwh=np.nan,  # no price: r_energy = -Wh
    )


def test_table_groups_interleaved_episodes_by_run():
    table = three_runs()
    assert [r.run_id for r in table.runs] == ["fast", "careful", "frugal"]
    assert table.run_index.tolist() == [0, 0, 1, 1, 2, 2]
    assert table.columns["mpl_units_per_hour"].tolist() == [100, 80, 40, 44, 50, 50]
    assert table.run_means(table.columns["error_rate"]) == pytest.approx([0.15, 0.02, 0.04])


def test_reward_terms_match_reward_builder_episode_by_episode():
    table = three_runs()
    terms = reward_term_matrix(table)
    first = build_reward_terms({"mpl": 100.0, "error_rate": 0.2, "energy_Wh": 30.0, "catastrophic": True})
    assert terms[0].tolist() == pytest.approx([first[name] for name in REWARD_TERM_NAMES])
    priced = EpisodeTable.from_arrays(table.runs, table.run_index, catastrophic=table.catastrophic,
                                      energy_price_usd_per_kwh=0.12, **table.columns)
    assert reward_term_matrix(priced)[0, 2] == -30.0  # Wh on a priced task too (spec §7)
    assert reward_term_matrix(priced, "usd")[0, 2] == pytest.approx(-0.12 * 30.0 / 1000.0)
    with pytest.raises(ValueError, match="energy_price_usd_per_kwh"):
        reward_term_matrix(table, "usd")  # the option needs a price


def test_utility_is_the_mean_episodic_combine_reward_and_orders_runs():
    table = three_runs()
    throughput = Objective("mpl_only", (1.0, 0.0, 0.0, 0.0, 0.0))
    energy = Objective("energy_heavy", (1.0, 0.0, 5.0, 0.0, 0.0))
    surface = solve_objective_surface(table, [throughput, energy], [])
    # fast: J = mean(100 - 5*30, 80 - 5*30) = -60; careful: 42 - 100 = -58; frugal: 50 - 25 = 25
    assert surface.utility[:, 1] == pytest.approx([-60.0, -58.0, 25.0])
    assert surface.utility[:, 0] == pytest.approx([90.0, 42.0, 50.0])
    assert surface.best_run[:, 0].tolist() == [0, 2]
    # against the scalar RewardBuilder path, episode by episode
    w = list(energy.weights)
    for r, run in enumerate(table.runs):
        eps = np.flatnonzero(table.run_index == r)
        js = [combine_reward(w, dict(zip(("r_mpl", "r_error", "r_energy", "r_safety", "r_novelty"),
                                         reward_term_matrix(table)[i], strict=True))) for i in eps]
        assert surface.utility[r, 1] == pytest.approx(np.mean(js)), run.run_id


def test_validity_on_run_means_and_fraction_of_episodes():
    table = three_runs()
    sets = [ConstraintSet(min_wage_parity=0.9, max_error_rate=0.05, name="parity_and_errors"),
            ConstraintSet(max_energy_Wh=2.5, name="energy_per_unit"),
            ConstraintSet(max_energy_Wh=10.0, energy_basis="per_episode", name="energy_per_episode")]
    errors_only = Objective("errors_only", (0.0, 1.0, 0.0, 0.0, 0.0))
    surface = solve_objective_surface(table, [*preset_objectives(["throughput"]), errors_only], sets)
    # parity_and_errors: fast mean error 0.15 > 0.05; careful mean parity 0.65 < 0.9; frugal means
    # (parity 0.9, error 0.04) meet it, yet only its second episode (1.0, 0.05) does -> 1 of 2.
    assert surface.valid[:, 0].tolist() == [False, False, True]
    assert surface.valid_fraction[:, 0].tolist() == [0.0, 0.0, 0.5]
    assert surface.valid[:, 1].tolist() == [False, True, True]
    assert surface.valid_fraction[:, 1].tolist() == [0.0, 1.0, 1.0]
    assert surface.valid[:, 2].tolist() == [False, False, True]
    assert surface.violation[0, 0] == pytest.approx(0.10)  # fast: error 0.15 - 0.05, parity met
    # throughput [2,1,0.5,1,0]: fast is the best run overall (J = 2*90 - 0.15 - 0.5*30 - 0.5 = 164.35), but
    # invalid under every set, so frugal is chosen everywhere; errors_only prefers careful where valid.
    assert surface.utility[:, 0] == pytest.approx([164.35, 73.98, 97.46])
    assert surface.best_run.tolist() == [[2, 2, 2], [2, 1, 2]]


def test_a_constraint_set_no_run_meets_says_so():
    table = three_runs()
    sets = [ConstraintSet(min_wage_parity=2.0, name="impossible"), ConstraintSet(name="free")]
    surface = solve_objective_surface(table, preset_objectives(["balanced"]), sets)
    assert surface.best_run[0].tolist() == [-1, int(np.argmax(surface.utility[:, 0]))]
    assert np.isnan(surface.best_utility()[0, 0])
    cell = surface_cells(surface)[0]
    assert (cell.valid, cell.best_run_id, cell.utility) == (False, None, None)
    assert "no run meets constraint set 'impossible'" in cell.note
    # fallback: highest J - 10*violation; parity violations 2 - (1.1, 0.65, 0.9)
    penalised = surface.utility[:, 0] - 10 * np.array([0.9, 1.35, 1.1])
    assert cell.fallback_run_id == table.runs[int(np.argmax(penalised))].run_id
    doc = surface_document(surface)
    assert doc["constraint_sets_no_run_meets"] == ["impossible"]
    assert "**No run meets constraint set `impossible`.**" in surface_markdown(doc)


def test_best_valid_cell_reports_datapacks_and_fraction():
    surface = solve_objective_surface(three_runs(), preset_objectives(["energy_saver"]),
                                      [ConstraintSet(max_error_rate=0.1, name="errors")])
    (cell,) = surface_cells(surface)
    assert cell.valid and cell.best_run_id == "frugal"
    assert cell.datapacks == ("dp_a", "dp_b")
    assert cell.valid_fraction == 1.0 and cell.runs_valid == 2


def test_simplex_grid_counts_and_sums():
    grid = simplex_grid(4)
    assert len(grid) == 35  # C(4+3, 3)
    assert len(simplex_grid(2, include_novelty=True)) == 15  # C(2+4, 4)
    weights = np.array([o.weights for o in grid])
    assert np.allclose(weights.sum(axis=1), 1.0) and np.all(weights[:, 4] == 0)
    assert len({o.name for o in grid}) == len(grid)


def two_runs_on_a_priced_task(price_usd_per_kwh: float = 0.12) -> EpisodeTable:
    """Two runs that differ only in energy: same MPL, errors, parity; 'frugal' 10 Wh, 'hungry' 40 Wh."""
    runs = [RunInfo("frugal", task_id="dishwashing"), RunInfo("hungry", task_id="dishwashing")]
    return EpisodeTable.from_arrays(
        runs, np.array([0, 0, 1, 1]),
        mpl_units_per_hour=np.array([60.0, 62.0, 60.0, 62.0]), error_rate=np.array([0.04, 0.02, 0.04, 0.02]),
        energy_wh=np.array([10.0, 10.0, 40.0, 40.0]), energy_wh_per_unit=np.array([0.2, 0.2, 0.8, 0.8]),
        wage_parity=np.array([0.9, 0.95, 0.9, 0.95]), energy_price_usd_per_kwh=price_usd_per_kwh)


def test_on_a_priced_task_energy_saver_picks_the_frugal_run_by_six_times_throughputs_margin():
    table = two_runs_on_a_priced_task()
    surface = solve_objective_surface(table, preset_objectives(["throughput", "energy_saver"]), [])
    frugal, hungry = surface.utility
    margin = dict(zip(["throughput", "energy_saver"], frugal - hungry, strict=True))
    assert surface.best_run[:, 0].tolist() == [0, 0]  # both presets prefer the frugal run
    # the margin is the energy weight times the 30 Wh saved: 0.5 * 30 and 3 * 30, so six times
    assert margin == pytest.approx({"throughput": 0.5 * 30.0, "energy_saver": 3.0 * 30.0})
    assert margin["energy_saver"] == pytest.approx(6.0 * margin["throughput"])
    # against an MPL term of ~60 the energy difference matters (it did not as 0.0036 USD)
    assert margin["energy_saver"] / surface.utility[0, 1] > 0.5
    # the priced option, asked for explicitly, gives the old dollar margins (3 * 0.0036 USD)
    priced = solve_objective_surface(table, [Objective.from_vector(ObjectiveVector.from_preset(
        "energy_saver", energy_term="usd"), "energy_saver_usd")], [])
    assert priced.utility[0, 0] - priced.utility[1, 0] == pytest.approx(3.0 * 30.0 * 0.12 / 1000.0)


def test_the_solver_utility_is_the_mean_of_episode_j_for_both_energy_terms():
    table = two_runs_on_a_priced_task()
    objectives = [Objective.from_vector(ObjectiveVector.from_preset("energy_saver", energy_term=term), term)
                  for term in ("wh", "usd")]
    surface = solve_objective_surface(table, objectives, [])
    economics = TaskEconomics(energy_price_usd_per_kwh=0.12)
    for k, term in enumerate(("wh", "usd")):
        vector = ObjectiveVector.from_preset("energy_saver", energy_term=term)
        for r, rec_run in enumerate(("frugal", "hungry")):
            js = [episode_j(rec, vector, economics) for rec in table.records() if rec["run_id"] == rec_run]
            assert surface.utility[r, k] == pytest.approx(np.mean(js), rel=1e-12)


def test_evaluate_datapacks_under_constraints_pools_the_episodes_as_the_spec_calls_it():
    from econmotor.analysis.objective_surface import evaluate_datapacks_under_constraints

    table = two_runs_on_a_priced_task()
    records = [r for r in table.records() if r["run_id"] == "frugal"]
    valid, utility = evaluate_datapacks_under_constraints(records, ObjectiveVector.from_preset("energy_saver"),
                                                          {"max_error_rate": 0.05, "max_energy_Wh": 20.0,
                                                           "energy_basis": "per_episode"})
    assert valid is True
    assert utility == pytest.approx(np.mean([episode_j(r, ObjectiveVector.from_preset("energy_saver"))
                                             for r in records]))
    valid_all, utility_all = evaluate_datapacks_under_constraints(table, "energy_saver",
                                                                  {"max_energy_Wh": 20.0,
                                                                   "energy_basis": "per_episode"})
    assert valid_all is False  # the pooled mean is 25 Wh per episode
    assert utility_all == pytest.approx(utility - 3.0 * 15.0)
    assert evaluate_datapacks_under_constraints(records, [1, 0, 0, 0, 0], None) == (True, pytest.approx(61.0))
