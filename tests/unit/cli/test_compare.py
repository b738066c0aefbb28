"""``econmotor compare``'s ranking: lowest price per unit first, and whether the intervals separate the two."""

from __future__ import annotations

from econmotor.cli.compare import rank


def _row(policy: str, price: float | None, low: float | None, high: float | None, units: float = 100.0) -> dict:
    return {"policy": policy, "price_usd_per_unit": price, "price_low": low, "price_high": high,
            "units_per_hour": units}


def test_lowest_price_wins_and_separated_intervals_say_so() -> None:
    ranked, summary = rank([_row("b", 0.12, 0.118, 0.122), _row("a", 0.11, 0.109, 0.111)])
    assert [r["policy"] for r in ranked] == ["a", "b"]
    assert summary.startswith("winner: a") and "larger than the intervals" in summary and "NOT" not in summary


def test_overlapping_intervals_are_not_a_clear_win() -> None:
    _, summary = rank([_row("a", 0.11, 0.10, 0.125), _row("b", 0.12, 0.115, 0.13)])
    assert "NOT larger than the intervals" in summary


def test_intervals_without_width_cannot_separate_policies() -> None:
    _, summary = rank([_row("a", 0.11, 0.11, 0.110001), _row("b", 0.12, 0.12, 0.12)])
    assert "narrower than 0.1% of the price" in summary and "datapack" in summary


def test_a_policy_without_a_finite_price_ranks_last() -> None:
    ranked, _ = rank([_row("none", None, None, None, 0.0), _row("a", 0.2, 0.19, 0.21)])
    assert [r["policy"] for r in ranked] == ["a", "none"]
