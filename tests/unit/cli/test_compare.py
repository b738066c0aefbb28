"""``econmotor compare``'s ranking: deployable policies first, lowest price per unit first, the refused ones after
them by their fall-rate bound (never by the price they are refused), whether the intervals separate the two, no
winner among policies that are not deployable; and its plot, which marks refused policies and draws the limit."""

from __future__ import annotations

import itertools

from econmotor.cli.compare import comparison_figure, rank


def _row(policy: str, price: float | None, low: float | None, high: float | None, units: float = 100.0,
         deployable: bool = True, bound: float | None = None) -> dict:
    return {"policy": policy, "price_usd_per_unit": price, "price_low": low, "price_high": high,
            "units_per_hour": units, "deployable": deployable, "fall_rate_bound": bound, "wh_per_unit": 1.0,
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
    ranked, summary = rank([_row("holosoma:g1_29dof/ppo", 0.1206, 0.1187, 0.1225, deployable=False, bound=0.26),
                            _row("holosoma:g1_29dof/fastsac", 0.1157, 0.1154, 0.1159, deployable=False, bound=0.22)])
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


def test_refused_policies_rank_after_the_deployable_by_their_fall_rate_bound_not_their_price() -> None:
    """The README's case: a G1 that fell in 20 of 20 episodes ranked first by a price it is refused."""
    ranked, summary = rank([_row("fell_every_time", 0.05, 0.04, 0.06, deployable=False, bound=1.0),
                            _row("falls_now_and_then", 0.3, 0.29, 0.31, deployable=False, bound=0.09),
                            _row("safe", 0.2, 0.19, 0.21, bound=0.03)])
    assert [r["policy"] for r in ranked] == ["safe", "falls_now_and_then", "fell_every_time"]
    assert summary.startswith("winner: safe")
    none_deployable, _ = rank([_row("fell_every_time", 0.05, 0.04, 0.06, deployable=False, bound=1.0),
                               _row("unknown", 0.01, 0.01, 0.01, deployable=False),
                               _row("falls_now_and_then", 0.3, 0.29, 0.31, deployable=False, bound=0.09)])
    # the lowest bound first; a policy without one (nothing attempted) last
    assert [r["policy"] for r in none_deployable] == ["falls_now_and_then", "fell_every_time", "unknown"]


def test_the_plot_marks_refused_policies_and_draws_the_acceptance_limit_on_the_fall_rate_panel() -> None:
    ranked, _ = rank([_row("safe", 0.2, 0.19, 0.21, bound=0.03),
                      _row("fell_every_time", 0.05, 0.04, 0.06, deployable=False, bound=1.0)])
    fig = comparison_figure(ranked, fall_rate_limit=0.05)
    price, *_, falls = fig.axes
    for ax in fig.axes:  # every panel: the refused bar hatched and grey, the deployable one plain
        safe_bar, refused_bar = ax.patches[:2]
        assert not safe_bar.get_hatch() and refused_bar.get_hatch()
        assert refused_bar.get_facecolor() != safe_bar.get_facecolor()
    assert [t.get_text() for t in price.texts] == ["refused"]  # its price is not one it may charge
    limits = [line for line in falls.get_lines() if list(line.get_ydata()) == [0.05, 0.05]]
    assert len(limits) == 1 and "0.05" in limits[0].get_label()


def test_a_row_quotes_the_fall_rate_bound_its_reports_verdict_used():
    """A sequential evaluation's verdict bounds the fall rate by its confidence sequence, wider than the
    report's fixed-count interval: the comparison shows and ranks by the verdict's bound, so a reader sees
    one number for one run."""
    from econmotor.cli.compare import comparison_row

    verdict_check = {"name": "error rate", "measured": 0.096, "bound": 0.396, "limit": 0.01, "passed": False}
    doc = {"pricing": {"aggregate": {"price_usd_per_unit": 0.13, "mpl_units_per_hour": 94.8}},
           "uncertainty": {"intervals": {"error_rate": {"point": 0.096, "low": 0.043, "high": 0.181}}},
           "runs": {"eval": {"config": {}}}, "recommendation": None,
           "metrics": {"econ": {"energy_wh_per_unit": 1.1}, "raw": {"errors": 6.0, "units_attempted": 62.5}},
           "verdict": {"label": "not deployable", "deployable": False, "checks": [verdict_check]},
           "registry": {"report_id": 1}}
    assert comparison_row("p", doc)["fall_rate_bound"] == 0.396
    doc["verdict"]["checks"] = []  # a report without the check: the interval's upper end
    assert comparison_row("p", doc)["fall_rate_bound"] == 0.181


def test_four_policies_given_as_paths_are_lettered_with_a_key_and_every_label_is_readable() -> None:
    """Four paths as tick labels ran into each other and off the figure (issue 52, item 7): the bars are
    lettered, a key names each path, and every label lies inside the figure, apart from its neighbours."""
    paths = ["runs/humanoid_locomotion_g1-20261202-035124-s0-6004/policy.onnx",
             "/home/team/exports/g1_finetuned_energy_weighted_v3.onnx",
             "runs/humanoid_locomotion_g1-20261203-101010-s1-7001/best/policy.onnx",
             "/home/team/exports/g1_finetuned_energy_weighted_v4.onnx"]
    ranked, _ = rank([_row(p, 0.12 + i / 100, 0.11 + i / 100, 0.13 + i / 100, bound=0.02)
                      for i, p in enumerate(paths)])
    fig = comparison_figure(ranked, fall_rate_limit=0.05)
    fig.canvas.draw()
    renderer, box = fig.canvas.get_renderer(), fig.bbox
    for ax in fig.axes:
        labels = [t for t in ax.get_xticklabels() if t.get_text()]
        extents = [t.get_window_extent(renderer) for t in labels]
        assert all(box.x0 <= e.x0 and e.x1 <= box.x1 and box.y0 <= e.y0 for e in extents)  # inside the figure
        assert all(a.x1 < b.x0 for a, b in itertools.pairwise(extents))  # apart from each other
        assert ax.get_position().height > 0.4  # a panel, not a strip
        assert [t.get_text() for t in labels] == ["A", "B", "C", "D"]
    key = "\n".join(t.get_text() for t in fig.texts)
    assert all(f"{letter}: {r['policy']}" in key for letter, r in zip("ABCD", ranked, strict=True))


def test_short_policy_names_label_the_bars_themselves() -> None:
    from econmotor.cli.compare import policy_labels

    assert policy_labels(["holosoma:g1_29dof/ppo", "holosoma:g1_29dof/fastsac", "exports/v3.onnx"]) == (
        ["g1_29dof/ppo", "g1_29dof/fastsac", "v3"], [])
    assert policy_labels(["a/policy.onnx", "b/policy.onnx"]) == (["A", "B"], ["A: a/policy.onnx", "B: b/policy.onnx"])
