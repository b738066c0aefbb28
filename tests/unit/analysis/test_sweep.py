"""Sweep planning, cell keys, failure recording and resuming (sequential, real backend and registry)."""

import numpy as np
import pytest

from econmotor.analysis.objective_surface import parse_vector_objective, preset_objectives
from econmotor.analysis.sweep import completed_cell_keys, plan_sweep, run_sweep
from econmotor.config.datapacks import parse_datapack
from econmotor.errors import ConfigError
from econmotor.store import Registry

GOOD = parse_datapack({"id": "dw_plain", "domain_randomization": {"p_min_range": [0.0, 0.01]}})
BAD = parse_datapack({"id": "dw_typo", "domain_randomization": {"friction_range": [0.5, 1.0]}})


def test_cell_keys_are_deterministic_and_change_with_every_input():
    objectives = preset_objectives(["throughput", "safety"])
    cells = plan_sweep("dishwashing", "dishwashing", objectives, [[GOOD], [BAD]], [0, 1], max_steps=100)
    assert len(cells) == 8 and len({c.key for c in cells}) == 8
    again = plan_sweep("dishwashing", "dishwashing", objectives, [[GOOD], [BAD]], [0, 1], max_steps=100)
    assert [c.key for c in again] == [c.key for c in cells]
    longer = plan_sweep("dishwashing", "dishwashing", objectives, [[GOOD], [BAD]], [0, 1], max_steps=101)
    assert not {c.key for c in longer} & {c.key for c in cells}
    edited = parse_datapack({"id": "dw_plain", "domain_randomization": {"p_min_range": [0.0, 0.02]}})
    assert plan_sweep("dishwashing", "dishwashing", objectives[:1], [[edited]], [0])[0].key != \
        plan_sweep("dishwashing", "dishwashing", objectives[:1], [[GOOD]], [0])[0].key


def test_a_grid_that_repeats_a_cell_is_refused():
    twice = [parse_vector_objective("2,1,0.5,1,0"), *preset_objectives(["throughput"])]
    with pytest.raises(ConfigError, match="repeats a cell"):
        plan_sweep("dishwashing", "dishwashing", twice, [[GOOD]], [0])


@pytest.mark.slow
def test_failed_cells_are_recorded_and_retried_completed_cells_skipped(tmp_path):
    registry = Registry(f"sqlite:///{tmp_path / 'reg.sqlite'}")
    cells = plan_sweep("dishwashing", "dishwashing", preset_objectives(["balanced"]), [[GOOD], [BAD]], [3],
                       max_steps=60, eval_episodes=2)
    seen = []
    outcomes = run_sweep(registry, cells, tmp_path / "policies", progress=lambda *a: seen.append(a))
    assert [o.status for o in outcomes] == ["completed", "failed"]
    assert "friction_range" in outcomes[1].error
    assert seen[-1] == ("sweep cells", 2, 2)
    runs = {r.id: r for r in registry.runs()}
    assert runs[outcomes[0].run_id].status == "completed"
    assert runs[outcomes[1].run_id].status == "failed" and "friction_range" in runs[outcomes[1].run_id].error
    assert runs[outcomes[0].run_id].config["cell_key"] == cells[0].key
    assert len(registry.episodes(run_ids=[outcomes[0].run_id])) == 2
    assert completed_cell_keys(registry, "dishwashing", "dishwashing") == {cells[0].key}
    # the cell's J is the one episode_j, and the solver ranks the recorded run by the same number
    from econmotor.analysis.objective_surface import solve_objective_surface
    from econmotor.analysis.sources import episodes_from_registry
    from econmotor.tasks import get_task
    from econmotor.valuation import episode_j

    summaries = [e.summary for e in registry.episodes(run_ids=[outcomes[0].run_id])]
    economics = get_task("dishwashing").economics
    assert outcomes[0].mean_j == pytest.approx(np.mean([episode_j(e, [1, 1, 1, 1, 0], economics) for e in summaries]))
    assert outcomes[1].mean_j is None
    surface = solve_objective_surface(episodes_from_registry(registry), preset_objectives(["balanced"]), [])
    assert surface.utility[0, 0] == pytest.approx(outcomes[0].mean_j, rel=1e-12)

    again = run_sweep(registry, cells, tmp_path / "policies")
    assert [o.status for o in again] == ["skipped", "failed"]
    assert len(registry.runs()) == 3  # the failed cell was tried again, the completed one was not


def test_a_cells_objective_keeps_its_energy_term():
    """The cell trains, records and selects under the objective it states, a priced energy term included."""
    from dataclasses import replace

    priced = replace(preset_objectives(["energy_saver"])[0], energy_term="usd")
    cell = plan_sweep("dishwashing", "dishwashing", [priced], [()], [0])[0]
    spec = cell.objective_spec()
    assert spec.energy_term == "usd" and spec.to_dict()["energy_term"] == "usd"
