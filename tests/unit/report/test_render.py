"""Report document, plots and renderings from a hand-made evaluation (no training)."""

from __future__ import annotations

import base64
import json
import math
import re
import stat
from pathlib import Path

import pytest

from econmotor.economics.pricing import PricingPolicy, price_evaluation
from econmotor.motor_backend.results import summarize_episodes
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.report.document import (
    REPORT_SCHEMA,
    REPORT_SCHEMA_VERSION,
    ReportContext,
    build_document,
)
from econmotor.report.plots import episode_distributions, render_plots, training_curve, unit_costs
from econmotor.report.render import render_html, render_markdown, write_report
from econmotor.report.text import fmt, headline, started_from_text, table_rows
from econmotor.tasks import get_task

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
# Three 30-minute shifts: 30, 20 and 0 clean dishes; 0, 2 and 3 errors; 50, 100 and 10 Wh.
RAW = [
    {"units_completed": 30, "errors": 0, "episode_length_s": 1800, "energy_wh": 50.0},
    {"units_completed": 20, "errors": 2, "episode_length_s": 1800, "energy_wh": 100.0},
    {"units_completed": 0, "errors": 3, "episode_length_s": 1800, "energy_wh": 10.0,
     "termination_reason": "catastrophic_error"},
]


#: ten steady one-hour shifts: 609 dishes, no error -> the error rate's 95% upper bound is 0.0049 (deployable)
STEADY = [{"units_completed": 60 + (i % 3), "errors": 0, "episode_length_s": 3600, "energy_wh": 100.0 + i}
          for i in range(10)]


def make_doc(curve=None, notes="n <b>", share=0.5, raw_episodes=RAW) -> dict:
    task = get_task("dishwashing")
    raw, econ, episodes = summarize_episodes(raw_episodes, task.economics)
    pricing = price_evaluation(task.economics, econ, episodes, PricingPolicy(share))
    ctx = ReportContext(task=task, backend="dishwashing", objective=EconomicObjectiveSpec(name="obj"),
                        datapack_ids=("dp1",), pricing=pricing, raw_metrics=raw, econ_metrics=econ,
                        episodes=episodes, training_curve=curve or [], notes=notes, db_url="sqlite:///x")
    return build_document(ctx)


def test_document_is_versioned_strict_json_with_hand_computed_prices():
    doc = make_doc()
    assert (doc["schema"], doc["schema_version"]) == (REPORT_SCHEMA, REPORT_SCHEMA_VERSION)
    text = json.dumps(doc, allow_nan=False)  # raises on inf/nan
    assert json.loads(text) == doc
    agg = doc["pricing"]["aggregate"]
    # pooled: 50 dishes in 1.5 h = 33.33/h; 160 Wh / 1.5 h = 0.10667 kWh/h
    # cost/h = 1.75 + 0.9 + 2.0 + 0.12*0.10667 = 4.6628; unit cost = 4.6628/33.333 = 0.139884
    assert agg["mpl_units_per_hour"] == pytest.approx(100 / 3)
    assert agg["robot_unit_cost_usd"] == pytest.approx((4.65 + 0.12 * 0.16 / 1.5) / (100 / 3))
    assert agg["price_usd_per_unit"] == pytest.approx(
        agg["robot_unit_cost_usd"] + 0.5 * (0.30 - agg["robot_unit_cost_usd"]))
    # the third shift completed nothing: its unit cost is infinite -> null in JSON, and p90 with it
    assert doc["episodes"][2]["robot_unit_cost_usd"] is None
    assert doc["pricing"]["distributions"]["robot_unit_cost_usd"]["p90"] is None
    assert doc["pricing"]["distributions"]["mpl_units_per_hour"]["p50"] == pytest.approx(40.0)
    names = {row["name"] for row in doc["inputs"]}
    assert {"wage_human_usd_per_hour", "robot_capex_usd", "spread_share", "robot_mpl_units_per_hour"} <= names
    assert doc["objective"]["overlay"] == {"mpl_per_hour": 1.0}
    assert doc["datapacks"] == ["dp1"] and doc["backend"] == "dishwashing"


def test_table_rows_and_headline_read_the_document():
    doc = make_doc()
    rows = {r[0].split(" (")[0]: r for r in table_rows(doc)}
    # label, aggregate, interval, mean, p10, p50, p90, unit
    assert rows["human unit cost"][1] == "0.3" and rows["human unit cost"][3:] == ("0.3",) * 4 + ("USD/unit",)
    assert rows["robot unit cost"][6] == "n/a"  # p90 is infinite
    assert rows["expected damage per unit"][1] == fmt(5 / 55)  # c_d 1.0 x pooled error rate
    # 5 errors in 55 dishes: the error rate's 95% upper bound 0.182 exceeds the human's 0.05 -> no price
    text = headline(doc)
    assert text.startswith("Not deployable: errors in 2 of 3 episodes (5 in 55 attempted); 95% upper bound on "
                           "the error rate 0.182 vs 0.05 accepted")
    assert "Charge" not in text and "Evidence: 3 evaluation episodes, 55 units attempted" in text
    steady = make_doc(raw_episodes=STEADY)
    text = headline(steady)
    rec = steady["recommendation"]
    assert text.startswith("Deployable: errors in none of 10 episodes (0 in 609 attempted); 95% upper bound on "
                           "the error rate 0.00491")  # 1 - 0.05**(1/609)
    assert f"Charge {fmt(rec['price_usd_per_unit'])} USD per clean dish" in text
    assert "robot's labour is worth" in text and "x a human's wage" in text and "10 robot-hours" in text
    assert "customer loses" not in text
    steady["pricing"]["aggregate"].update(damage_usd_per_unit=1.65, customer_saving_after_damage_usd_per_hour=-12.5)
    assert "With damage of 1.65 USD per" in headline(steady) and "the customer loses 12.5 USD/h" in headline(steady)
    assert fmt(None) == "n/a" and fmt(math.inf) == "n/a" and fmt(12345.6) == "12,346" and fmt(0.123456) == "0.1235"


def test_plots_are_png_and_absent_without_data():
    doc = make_doc(curve=[{"timesteps": 100, "mean_return": 1.0}, {"timesteps": 200, "mean_return": 2.0}])
    for make in (episode_distributions, training_curve, unit_costs):
        assert make(doc).startswith(PNG_MAGIC)
    assert training_curve(make_doc()) is None
    assert set(render_plots(make_doc())) == {"unit_costs", "episode_distributions"}


def test_markdown_and_html_are_complete_and_self_contained():
    doc = make_doc(curve=[{"timesteps": 100, "mean_return": 1.0}])
    plots = render_plots(doc)
    md = render_markdown(doc, {k: f"p/{k}.png" for k in plots})
    assert md.startswith("# Task pricing report: dishwashing")
    assert "| price per unit at the point estimate |" in md and "![training_curve](p/training_curve.png)" in md
    assert "## Verdict: not deployable" in md and "Recommended price" not in md
    assert "| wage_human_usd_per_hour | 18 | USD/h |" in md
    page = render_html(doc, plots)
    assert "n &lt;b&gt;" in page and "<b>" not in page  # notes are escaped
    assert not re.search(r"""(src|href)=["']?(https?:|//|file:)""", page)  # nothing external
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(images) == 3 and all(base64.b64decode(i).startswith(PNG_MAGIC) for i in images)


def test_write_report_lands_all_files_readable_and_leaves_no_temporaries(tmp_path: Path):
    doc = make_doc()
    files = write_report(doc, tmp_path / "out", "r1", json_path=tmp_path / "elsewhere" / "doc.json")
    assert files == {"json": str(tmp_path / "elsewhere" / "doc.json"), "markdown": str(tmp_path / "out" / "r1.md"),
                     "html": str(tmp_path / "out" / "r1.html")}
    assert json.loads(Path(files["json"]).read_text()) == doc
    assert (tmp_path / "out" / "r1_plots" / "unit_costs.png").read_bytes().startswith(PNG_MAGIC)
    leftovers = [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]
    assert leftovers == []
    assert Path(files["html"]).stat().st_mode & stat.S_IRGRP  # not the 0600 of a temporary file


def test_a_run_started_from_a_walker_says_so_in_the_document_and_the_report():
    from econmotor.store.records import RunRecord

    init = {"policy": "holosoma:g1_29dof/ppo", "sha256": "ab12cd34ef56" + "0" * 52, "hidden_sizes": [512, 256, 128],
            "activation": "elu", "critic_warmup_iterations": 10, "onnx_path": "/x/ppo_g1_29dof.onnx"}
    train = RunRecord(id=4, kind="train", task_id="dishwashing", backend="mjx", status="completed",
                      objective_name="obj", objective={}, datapack_ids=(), config={"backend_config": {
                          "init_policy": init}}, seed=0, num_envs=16, max_steps=32000, policy_path="runs/g1",
                      raw_metrics={}, econ_metrics={}, training_curve=[], artifacts={}, notes="", error=None,
                      parent_run_id=None, robot_id=None, created_at=None, finished_at=None)
    doc = make_doc()
    task = get_task("dishwashing")
    raw, econ, episodes = summarize_episodes(RAW, task.economics)
    ctx = ReportContext(task=task, backend="mjx", objective=EconomicObjectiveSpec(name="obj"), datapack_ids=(),
                        pricing=price_evaluation(task.economics, econ, episodes, PricingPolicy(0.5)),
                        raw_metrics=raw, econ_metrics=econ, episodes=episodes, training_curve=[], notes="",
                        db_url="sqlite:///x", train_run=train)
    started = build_document(ctx)["started_from"]
    assert started == {k: init[k] for k in ("policy", "sha256", "hidden_sizes", "activation",
                                            "critic_warmup_iterations")}
    assert doc["started_from"] is None  # a fresh actor: nothing to say
    assert started_from_text(started) == ("holosoma:g1_29dof/ppo (sha256 ab12cd34ef56; actor 512 -> 256 -> 128, "
                                          "elu), fine-tuned for this objective after 10 critic-only iterations")
    md = render_markdown(build_document(ctx), {})
    assert "| started from | holosoma:g1_29dof/ppo (sha256 ab12cd34ef56; actor 512 -&gt; 256" in md


def test_the_evaluated_line_reads_the_recorded_provenance_not_a_backends_keys():
    from econmotor.motor_backend.results import EvalProvenance
    from econmotor.report.text import imported_policy_text

    walked = EvalProvenance(evaluator="sim2sim", figures_from="MuJoCo sim-to-sim (the card)", imported=True,
                            commanded_speed_m_per_s=0.8, achieved_speed_m_per_s=0.66)
    eval_run = {"policy_path": "holosoma:g1_29dof/ppo",
                "config": {"provenance": walked.to_dict(), "backend_config": {"figures_from": "not read"}}}
    text = imported_policy_text(eval_run)
    assert text.startswith("imported policy holosoma:g1_29dof/ppo (trained elsewhere; nothing trained here); "
                           "figures from MuJoCo sim-to-sim (the card); speed achieved 0.66")
    assert text.endswith("m/s commanded, while walking") and "not read" not in text
    hopper = EvalProvenance(evaluator="mujoco", figures_from="Gymnasium MuJoCo Hopper-v5")
    assert imported_policy_text({"policy_path": "runs/x", "config": {"provenance": hopper.to_dict()}}) == ""
    assert imported_policy_text(None) == "" and imported_policy_text({"config": {}}) == ""
