"""One pricer for the card-robot walker: held-out selection, the evaluation after training and a report walk the
same episodes (locomotion/evaluation.py: ``evaluate``; motor_backend/walker_pricing.py; mujoco/walker_training.py).

The shipped G1 PPO walker starts a mujoco-backend run under ``humanoid_stress`` (the run the backend builds:
``walker_backend.walker_run``). One held-out evaluation of its actor (four episodes, looks of two) alternates
the nominal conditions and the training's stress; the same seeds are then priced

- by the evaluation after training (``evaluate_walker_task`` on the run's exported ``policy.onnx``), nominal and
  under the datapack: the same episodes, float for float (one ONNX, one evaluator);
- by a report of the shipped walker (the holosoma backend's imported-policy pricing): the same episodes within
  a tight tolerance (relative 1e-6; equal float for float where this was written), because the run's ONNX is the
  shipped one read into torch and written back: the same float32 weights in another graph, which onnxruntime
  may round differently on another CPU, and a walk carries a last-bit difference on (the torch actor the old
  in-process selection walked differed from its own ONNX by ~3e-8 relative in a 3 s episode's legs and Wh).

Episodes of 3 s (the catalog's course, cut at its time limit) keep it short.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from econmotor.config.datapacks import load_datapack_configs
from econmotor.locomotion.conditions import walker_setup
from econmotor.motor_backend.holosoma.host.backend import HolosomaBackend
from econmotor.motor_backend.mujoco import walker_backend as wb
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.walker_training import ONNX_FILE
from econmotor.motor_backend.selection import Selection, SelectionConfig
from econmotor.objectives.economic_objective import EconomicObjectiveSpec
from econmotor.tasks import get_task

pytestmark = [pytest.mark.holosoma]  # the shipped G1 walker

REPO = Path(__file__).parents[2]
POLICY, TASK = "holosoma:g1_29dof/ppo", "humanoid_locomotion_g1"
EPISODE_S, EPISODES, LOOK, SEED = 3.0, 4, 2, 7
#: an episode's raw metrics a price is made of
RAW = ("units_completed", "units_attempted", "errors", "energy_wh", "episode_length_s", "length_steps",
       "risk_score")


def test_selection_the_evaluation_after_training_and_a_report_price_the_same_episodes(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    spec = get_task(TASK)
    short = {**wb.walker_settings(spec), "sim2sim_episode_s": EPISODE_S}
    monkeypatch.setattr(wb, "walker_settings", lambda _spec: short)  # the run's and its evaluation's course
    [pack] = load_datapack_configs([REPO / "configs/datapacks/humanoid_stress.yaml"])
    objective = EconomicObjectiveSpec()
    selection = Selection(spec, objective, SelectionConfig(every_steps=1, episodes=EPISODES, seed=SEED, batch=LOOK))
    run_dir = tmp_path / "run"
    readings = []  # the run reads the task's conditions once (its held-out nominal conditions come with them)
    monkeypatch.setattr(wb, "walker_setup", lambda *a, **k: readings.append(a) or walker_setup(*a, **k))
    run, config = wb.walker_run(spec, objective, [pack], run_dir, num_envs=4, max_steps=1, seed=SEED,
                                init_policy=POLICY, hyperparameters=None, selection=selection, resume=False,
                                max_wall_s=None, described={})
    assert config["selection_conditions"] == ["nominal", "humanoid_stress"]
    assert len(readings) == 1

    looks: list[list[dict]] = []
    learner, first = run.learner(), selection.config.first_seed
    held_out = run.evaluate(learner, EPISODES, first, lambda rows: looks.append(list(rows)) or False)
    assert len(held_out) == EPISODES
    assert looks == [held_out[:LOOK], held_out]  # stop asked after each look, the rows in episode order
    assert ["stress_friction" in r for r in held_out] == [False, True, False, True]  # nominal, stress, ...
    # one process steps both conditions' robots together (locomotion.env.run_batches): the same episodes
    run.select_workers = 1
    assert run.evaluate(learner, EPISODES, first, lambda rows: False) == held_out

    # the evaluation after training: the run's own export of the same actor, priced on the same seeds
    run_dir.mkdir(parents=True, exist_ok=True)
    run.export(learner.net.layers(), run_dir / ONNX_FILE)
    mujoco = MujocoBackend(eval_workers=1)
    after = {name: wb.evaluate_walker_task(mujoco, str(run_dir), spec, num_episodes=EPISODES, seed=first,
                                           datapack_configs=packs, output_dir=tmp_path / f"after_{name}",
                                           progress=lambda *_: None, stop=None).episodes
             for name, packs in (("nominal", []), ("stress", [pack]))}
    for i, row in enumerate(held_out):
        priced = after["nominal" if i % 2 == 0 else "stress"][i]
        assert {k: priced[k] for k in (*RAW, "termination_reason")} == \
            {k: row[k] for k in (*RAW, "termination_reason")}, f"held-out episode {i}"
    # the look priced the file the run exports: selection prices what it keeps
    assert (run_dir / "selection" / "candidate.onnx").read_bytes() == (run_dir / ONNX_FILE).read_bytes()

    # a report of the shipped walker on the same seeds and conditions (the holosoma backend's pricing)
    holosoma = HolosomaBackend(venv=REPO / ".venv-holosoma", eval_episode_length_s=EPISODE_S, eval_workers=1)
    report = {name: holosoma.evaluate_policy(POLICY, TASK, objective, EPISODES, first, datapack_configs=packs,
                                             output_dir=tmp_path / f"report_{name}").episodes
              for name, packs in (("nominal", []), ("stress", [pack]))}
    for i, row in enumerate(held_out):
        priced = report["nominal" if i % 2 == 0 else "stress"][i]
        assert priced["termination_reason"] == row["termination_reason"]
        for key in RAW:  # float32 weights through another graph (module docstring)
            assert priced[key] == pytest.approx(row[key], rel=1e-6, abs=1e-9), f"held-out episode {i}: {key}"


class _Captured(Exception):
    pass


def test_a_walker_held_out_evaluation_may_run_to_a_hundred_legs(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """A walker's held-out look runs 100 legs or more of its task's course (34 episodes of the G1's 3 legs) before
    the sequential plan is asked, so every look can see falls."""
    for task in ("humanoid_locomotion_g1", "humanoid_locomotion_t1"):
        legs = int(wb.walker_settings(get_task(task))["sim2sim_legs"])
        assert wb.WALKER_SELECT_BATCH * legs >= wb.MIN_SELECT_LEGS, task
    assert wb.WALKER_SELECT_EPISODES >= wb.WALKER_SELECT_BATCH
    seen: dict[str, Selection] = {}

    def capture(*_args, selection: Selection, **_kwargs):
        seen["selection"] = selection
        raise _Captured

    monkeypatch.setattr(wb, "train_walker", capture)
    with pytest.raises(_Captured):
        wb.train_walker_task(MujocoBackend(), get_task(TASK), objective=EconomicObjectiveSpec(), datapack_configs=[],
                             num_envs=4, max_steps=10**6, seed=0, output_dir=tmp_path, eval_episodes=0,
                             progress=lambda *_: None, resume=False, hyperparameters=None, select_every_steps=None,
                             select_episodes=None, until_deployable=False, init_policy=None, max_wall_s=None)
    config = seen["selection"].config
    assert config.episodes == wb.WALKER_SELECT_EPISODES and config.plan.looks[:2] == (34, 68)
