"""``econmotor compare``'s ranking: deployable policies first, lowest price per unit first, whether the intervals
separate the two, and no winner among policies that are not deployable."""

from __future__ import annotations

from econmotor.cli.compare import rank


def _row(policy: str, price: float | None, low: float | None, high: float | None, units: float = 100.0,
         deployable: bool = True) -> dict:
    return {"policy": policy, "price_usd_per_unit": price, "price_low": low, "price_high": high,
            "units_per_hour": units, "deployable": deployable,
            "charge_usd_per_unit": high if deployable else None}  # a report charges the cautious end


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


def test_no_winner_when_no_policy_is_deployable() -> None:
    # the walkthrough's case: both not deployable, separated intervals; the old summary named a priced winner
    ranked, summary = rank([_row("holosoma:g1_29dof/ppo", 0.1206, 0.1187, 0.1225, deployable=False),
                            _row("holosoma:g1_29dof/fastsac", 0.1157, 0.1154, 0.1159, deployable=False)])
    assert [r["policy"] for r in ranked] == ["holosoma:g1_29dof/fastsac", "holosoma:g1_29dof/ppo"]
    assert summary.startswith("no winner: none of the 2 policies is deployable")
    assert "winner:" not in summary.removeprefix("no winner:") and "USD/unit" not in summary
    assert "fastsac" not in summary and "larger than the intervals" not in summary


def test_a_cheaper_policy_that_is_not_deployable_cannot_win() -> None:
    ranked, summary = rank([_row("cheap", 0.05, 0.04, 0.06, deployable=False), _row("safe", 0.2, 0.19, 0.21)])
    assert [r["policy"] for r in ranked] == ["safe", "cheap"]
    assert summary.startswith("winner: safe, charging 0.21 USD/unit (its report's price; point estimate 0.2); "
                              "the only deployable one of the 2 policies")
    assert "larger than the intervals" not in summary


def test_the_winner_line_quotes_the_price_its_report_charges() -> None:
    """The report charges the cautious end of the intervals; the line says that figure, and the point estimate."""
    _, summary = rank([{**_row("a", 0.1, 0.09, 0.11), "charge_usd_per_unit": 0.108}, _row("b", 0.2, 0.19, 0.21)])
    assert summary.startswith("winner: a, charging 0.108 USD/unit (its report's price; point estimate 0.1)")


def test_only_deployable_policies_are_compared_for_the_win() -> None:
    ranked, summary = rank([_row("cheap", 0.05, 0.04, 0.06, deployable=False), _row("b", 0.2, 0.19, 0.21),
                            _row("a", 0.1, 0.09, 0.11)])
    assert [r["policy"] for r in ranked] == ["a", "b", "cheap"]
    assert summary.startswith("winner: a, charging 0.11 USD/unit (its report's price; point estimate 0.1); "
                              "the difference is larger than the intervals")
    assert "below b's" in summary and summary.endswith("not deployable, so not in the running: cheap")
