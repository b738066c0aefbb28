"""``econmotor compare``'s console table at 80 columns: nothing cut to an ellipsis, every policy id whole."""

from __future__ import annotations

import io

from rich.console import Console

from econmotor.cli.compare import COLUMNS, comparison_table


def _row(policy: str, price: float) -> dict:
    return {"policy": policy, "price_usd_per_unit": price, "price_low": price - 0.0003,
            "price_high": price + 0.0002, "units_per_hour": 104.7, "wh_per_unit": 1.098, "falls": 3,
            "fall_rate_bound": 0.2231, "achieved_speed_m_per_s": 0.6612, "commanded_speed_m_per_s": 1.0,
            "mean_mech_power_w": 51.99, "mean_power_w": 115.2, "verdict": "not deployable", "deployable": False}


POLICIES = ("holosoma:g1_29dof/fastsac", "holosoma:g1_29dof/ppo")
TITLE = "humanoid_locomotion_g1: 2 policies, 10 episodes each, seeds 1000-1009"


def _render(rows: list[dict], width: int) -> str:
    out = Console(width=width, record=True, file=io.StringIO())
    out.print(comparison_table(rows, TITLE, out))
    return out.export_text()


def test_two_policies_at_80_columns_fit_uncut_with_a_column_per_policy() -> None:
    text = _render([_row(POLICIES[0], 0.1157), _row(POLICIES[1], 0.1206)], 80)
    assert "…" not in text
    assert max(len(line) for line in text.splitlines()) <= 80
    header = next(line for line in text.splitlines() if POLICIES[0] in line)
    assert POLICIES[1] in header and header.index(POLICIES[0]) < header.index(POLICIES[1])  # rank order
    for figure in COLUMNS[1:]:  # every figure, named whole
        assert figure in text
    for cell in ("0.1154 - 0.1159", "0.6612 / 1", "51.99 / 115.2", "not deployable", "0.2231"):
        assert cell in text


def test_a_wide_console_keeps_one_row_per_policy() -> None:
    text = _render([_row(POLICIES[0], 0.1157), _row(POLICIES[1], 0.1206)], 200)
    rows = [line for line in text.splitlines() if "holosoma:" in line]
    assert len(rows) == 2 and all("not deployable" in line for line in rows)
    assert all(column in text for column in COLUMNS) and "…" not in text


def test_many_policies_at_80_columns_fold_rather_than_cut() -> None:
    rows = [_row(f"holosoma:g1_29dof/policy_{i}", 0.11 + i / 100) for i in range(5)]
    text = _render(rows, 80)
    assert "…" not in text
    assert max(len(line) for line in text.splitlines()) <= 80
