"""The walker trainer's collection in worker processes (issue 54, item 3: both cores for one run;
motor_backend/mujoco/walker_collect.py).

- two workers collect a rollout of the shapes and episode accounting one process collects, finite, every
  robot's episodes seeded from the run's range and no seed twice;
- a run with two workers is reproducible: the same seed collects the same rollouts, before and after an update;
- the workers end when the trainer's process is killed (SIGKILL: no cleanup runs in it);
- a run with two workers resumes from its checkpoint with two workers, from the seeds the checkpoint kept;
- under ``policy_lag: 1`` the next batch is stepped while the update runs: an update learns from the batch the
  actor one update back collected (in one process and in workers), and a run closed with a batch in flight
  leaves no worker behind.

Small robots counts and short iterations of the shipped G1 PPO walker; every pool is closed (the trainer's
``close``) and the killed trainer's process group is killed whatever happens.
"""

from __future__ import annotations

import copy
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.couriers.onnx_actor import policy_file, read_actor
from econmotor.couriers.policy_import import resolve_contract
from econmotor.locomotion import course as crs
from econmotor.locomotion.conditions import WalkerSetup
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings
from econmotor.motor_backend.mujoco import walker_collect as wc
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
from econmotor.motor_backend.mujoco.walker_training import (
    CHECKPOINT_FILE,
    TRAIN_SEED_BASE,
    WalkerLearner,
    WalkerTrainingRun,
)
from econmotor.objectives.loader import objective_from_vector
from econmotor.tasks import get_task

from .test_walker_eval_parent_death import kill_once_stepping

pytestmark = [pytest.mark.holosoma]  # the shipped G1 walker

POLICY = "holosoma:g1_29dof/ppo"
METER = MeterSettings(leg_distance_m=2.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.2,
                      fall_tilt_rad=0.8)
#: short episodes (3 s) on a short course: episodes end (truncated, fallen) within a few iterations
COURSE = crs.CourseSettings(leg_m=2.0, dwell_s=0.5, speed_m_per_s=0.8, legs=2)
WEIGHTS = {"tracking_lin_vel": 2.0, "tracking_ang_vel": 1.5, "penalty_orientation": -10.0, "alive": 1.0}
RECIPE = {"num_envs": 6, "steps_per_iteration": 40, "num_minibatches": 2, "num_epochs": 1,
          "critic_warmup_iterations": 0, "critic_hidden_sizes": [32, 32]}


def _run(run_dir: Path, workers: int, seed: int = 3, max_steps: int = 10**9, policy: str = POLICY, **recipe
         ) -> WalkerTrainingRun:
    contract = resolve_contract(policy)
    setup = WalkerSetup(contract=contract, card=contract.card, course=COURSE, meter=METER,
                        stress=Stress(friction_range=(0.5, 1.0), payload_kg_range=(0.0, 3.0)), episode_s=3.0,
                        notes=(), datapack_ids=())
    return WalkerTrainingRun(
        run_dir=run_dir, setup=setup, cfg=WalkerPPOConfig.from_mapping({**RECIPE, **recipe}),
        objective=objective_from_vector(ObjectiveVector.from_preset("energy_saver"), "energy_saver"),
        economics=get_task("humanoid_locomotion_g1").economics, gain=2.0, weights=WEIGHTS, params={}, seed=seed,
        max_steps=max_steps, init=read_actor(policy_file(policy), policy), kp=np.asarray(contract.kp),
        kd=np.asarray(contract.kd), command_ranges=contract.command_ranges, checkpoint_every_s=1e9,
        collect_workers=workers)


def _collect(learner: WalkerLearner, iterations: int) -> list[tuple]:
    """``iterations`` rollouts, each followed by its update; (rollout, last value, episodes, parts) each."""
    out = []
    for _ in range(iterations):
        rollout, last_value, episodes, parts = learner.collect()
        out.append((rollout, last_value, episodes, parts))
        learner.ppo.update(rollout, last_value)
    return out


def test_two_workers_collect_what_one_process_does(tmp_path: Path) -> None:
    shapes, counted = {}, {}
    for workers in (1, 2):
        learner = WalkerLearner(_run(tmp_path, workers))
        try:
            assert learner.workers == workers
            rollouts = _collect(learner, 2)
            seeds = learner.next_seeds
        finally:
            learner.close()
        assert learner.collection is None
        rollout, last_value, _, parts = rollouts[-1]
        shapes[workers] = {k: tuple(v.shape) for k, v in vars(rollout).items()} | {"last": tuple(last_value.shape)}
        episodes = [ep for *_, eps, _ in rollouts for ep in eps]
        dones = sum(int(r.dones.sum()) for r, *_ in rollouts)
        assert dones == len(episodes) > 0  # every ended episode's step is a done, and no other step
        for r, value, eps, p in rollouts:
            for name, tensor in [*vars(r).items(), ("last_value", value)]:
                assert torch.isfinite(tensor).all(), name
            assert all(np.isfinite(ep["energy_wh"]) and np.isfinite(ep["units_completed"]) for ep in eps)
            assert np.isfinite(p["locomotion"]) and np.isfinite(p["economic"])
        # episodes started: the 6 robots' first ones and one per ended episode, from the run's range, worker w
        # of W taking the seeds w apart modulo W
        first = TRAIN_SEED_BASE + 3 * 1_000_000
        assert [(s - first) % workers for s in seeds] == list(range(workers))
        assert sum((s - first) // workers for s in seeds) == 6 + len(episodes)
        counted[workers] = (len(episodes), sorted(parts))
    assert shapes[1] == shapes[2]
    assert shapes[2]["obs"][:2] == (40, 6) and shapes[2]["last"] == (6,)
    assert counted[1][1] == counted[2][1]  # the same reward parts


def test_workers_started_from_fastsac_act_with_the_trainers_moved_actor(tmp_path: Path) -> None:
    """From the shipped FastSAC walker, each worker rebuilds its actor (normaliser, layer norms, tanh head) from
    what it is sent and reloads it after an update: the means it sampled around are the trainer's actor's."""
    learner = WalkerLearner(_run(tmp_path, 2, policy="holosoma:g1_29dof/fastsac"))
    try:
        net = learner.ppo.net
        for _ in range(2):
            rollout, last_value, *_ = learner.collect()
            with torch.no_grad():
                np.testing.assert_allclose(rollout.means.numpy(), net.actor(rollout.obs).numpy(), atol=1e-5)
            assert torch.isfinite(last_value).all()
            stats = learner.ppo.update(rollout, last_value)
            assert stats["kl"] > 0.0  # the actor moved: the next chunk is collected by the moved actor
    finally:
        learner.close()


def test_two_workers_are_reproducible(tmp_path: Path) -> None:
    runs = []
    for _ in range(2):
        torch.manual_seed(0)
        learner = WalkerLearner(_run(tmp_path, 2))
        try:
            runs.append(_collect(learner, 2))  # the second rollout under the updated actor
        finally:
            learner.close()
    for (r1, v1, e1, p1), (r2, v2, e2, p2) in zip(*runs, strict=True):
        for name in vars(r1):
            assert torch.equal(getattr(r1, name), getattr(r2, name)), name
        assert torch.equal(v1, v2) and e1 == e2 and p1 == p2
    # another run seed, other episodes
    learner = WalkerLearner(_run(tmp_path, 2, seed=4))
    try:
        other = learner.collect()[0]
    finally:
        learner.close()
    assert not torch.equal(other.obs, runs[0][0][0].obs)


PARENT = r"""
import sys
from pathlib import Path
sys.path.insert(0, {repo!r})
from tests.integration.test_walker_collect_workers import _run
from econmotor.motor_backend.mujoco.walker_training import WalkerLearner

learner = WalkerLearner(_run(Path({run_dir!r}), 2, steps_per_iteration=100000, num_minibatches=1))
learner.collect()  # stepping for minutes
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_the_workers_end_when_the_trainer_is_killed(tmp_path: Path) -> None:
    script = PARENT.format(repo=str(Path(__file__).parents[2]), run_dir=str(tmp_path))
    parent = subprocess.Popen([sys.executable, "-c", script], env={**os.environ, "OMP_NUM_THREADS": "1"},
                              start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        kill_once_stepping(parent, 2, start_s=120)
    finally:
        try:
            os.killpg(parent.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        parent.wait()
        parent.stderr.close()


def test_a_run_with_workers_resumes_from_its_checkpoint(tmp_path: Path) -> None:
    """Interrupted (Ctrl-C) after its first iteration, the run checkpoints and closes its workers; resumed, it
    continues with two workers from the seeds its checkpoint kept."""
    import multiprocessing

    per_iteration = 6 * 40
    run_dir = tmp_path / "run"
    config = {"task_id": "humanoid_locomotion_g1"}

    def interrupt(message: str, done: float, total: float) -> None:
        if " steps, " in message:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _run(run_dir, 2).train(config=config, progress=interrupt)
    assert multiprocessing.active_children() == []  # the workers were closed
    state = torch.load(run_dir / CHECKPOINT_FILE, weights_only=False)["state"]
    assert state["env_steps"] == per_iteration
    kept = state["next_seeds"]
    base = TRAIN_SEED_BASE + 3 * 1_000_000
    assert len(kept) == 2 and kept[0] % 2 == base % 2 and kept[1] % 2 == (base + 1) % 2  # interleaved
    assert min(kept) >= base + 6  # past the 6 robots' first episodes
    resumed_from: list[list[int]] = []
    original = WalkerTrainingRun.collector

    def spy(self, seeds, iteration):
        resumed_from.append(list(seeds))
        return original(self, seeds, iteration)

    run = _run(run_dir, 2, max_steps=2 * per_iteration)
    run.collector = spy.__get__(run)
    outcome = run.train(resume=True, config=config)
    assert resumed_from == [kept]  # the workers restarted from the checkpoint's seeds
    rows = [json.loads(line) for line in (run_dir / "curve.jsonl").read_text().splitlines()]
    assert [r["iteration"] for r in rows] == [1, 2] and all(r["collect_s"] > 0 for r in rows)
    assert outcome.config["trained_steps"] == 2 * per_iteration
    assert outcome.config["timing"]["collect_workers"] == 2
    again = torch.load(run_dir / CHECKPOINT_FILE, weights_only=False)["state"]["next_seeds"]
    assert all(a > k for a, k in zip(again, kept, strict=True))
    # resumed with another worker count: its workers start after every seed used
    assert wc.resumed_seeds(again, 3) == [max(again) + w for w in range(3)]
    assert wc.resumed_seeds([base + 40], 1) == [base + 40]  # a checkpoint of one process's run


def test_a_failing_worker_is_a_backend_error_naming_its_cause(tmp_path: Path) -> None:
    from econmotor.errors import BackendError

    run = _run(tmp_path, 2)
    run.weights = {"feet_air_time": 1.0}  # a term the walker env cannot compute: the workers' env build fails
    learner = WalkerLearner(run)
    try:
        with pytest.raises(BackendError, match="feet_air_time"):
            learner.collect()
    finally:
        learner.close()
    assert learner.collection is None


def test_held_out_looks_alternate_nominal_and_the_training_stress(tmp_path: Path) -> None:
    """A run under a datapack is selected on both conditions: held-out episode ``i`` runs under
    ``select_stresses[i % 2]`` (nominal, then the training's stress), each on its own seed, in order; a look's
    verdict then sees the falls the stress causes."""
    import dataclasses

    run = _run(tmp_path / "run", workers=1)
    nominal = Stress()
    run = dataclasses.replace(run, select_stresses=(nominal, run.setup.stress))
    looks: list[int] = []
    rows = run.evaluate(run.learner(), 4, 50_000, lambda rows: looks.append(len(rows)) or False)
    assert len(rows) == 4 and looks == [len(rows)]  # one look of the whole batch (no selection: the batch)
    stressed = ["stress_friction" in r for r in rows]  # a friction drawn: the stress's episodes
    assert stressed == [False, True, False, True]
    assert rows[0]["stress_payload_kg"] == 0.0 and rows[1]["stress_payload_kg"] > 0.0
    # the same episodes alone under each condition: the seeds are the look's (50,000 + i)
    alone = dataclasses.replace(run, select_stresses=(run.setup.stress,))
    again = alone.evaluate(alone.learner(), 4, 50_000, lambda rows: False)
    # the look prices the run's ONNX export (locomotion.evaluation.evaluate): an episode depends on its seed only
    assert again[1] == rows[1] and again[3] == rows[3]


def test_the_update_runs_on_every_usable_cpu_while_the_workers_wait_and_gives_the_threads_back(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from econmotor.motor_backend.mujoco.walker_ppo import WalkerPPO

    during: list[int] = []
    update = WalkerPPO.update
    monkeypatch.setattr(WalkerPPO, "update",
                        lambda self, *a: during.append(torch.get_num_threads()) or update(self, *a))
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        for workers in (2, 1):
            learner = WalkerLearner(_run(tmp_path / f"w{workers}", workers))
            try:
                learner.learn(1)
            finally:
                learner.close()
            assert torch.get_num_threads() == 1  # the process's own setting, back
        assert learner.timing()["update_threads"] == 1
    finally:
        torch.set_num_threads(before)
    # with workers, their cores are idle while the update runs; in one process it keeps the process's threads
    assert during == [wc.usable_cpus(), 1]


@pytest.mark.parametrize("workers", [1, 2])
def test_policy_lag_one_learns_from_the_batch_the_previous_actor_collected(tmp_path: Path, workers: int) -> None:
    learner = WalkerLearner(_run(tmp_path, workers, policy="holosoma:g1_29dof/fastsac", policy_lag=1))
    net = learner.ppo.net
    behaviour = copy.deepcopy(net.actor)  # the actor that collected the batch the next collect() returns
    try:
        for iteration in range(3):
            rollout, last_value, *_ = learner.collect()
            assert learner.collection is not None and learner.collection.pending  # the next batch, stepping
            with torch.no_grad():
                np.testing.assert_allclose(rollout.means.numpy(), behaviour(rollout.obs).numpy(), atol=1e-5)
                if iteration:  # the actor has moved since: its means are not the batch's
                    assert not np.allclose(rollout.means.numpy(), net.actor(rollout.obs).numpy(), atol=1e-4)
            behaviour = copy.deepcopy(net.actor)
            assert learner.ppo.update(rollout, last_value)["kl"] > 0.0
        procs = list(getattr(learner.collection, "procs", []))
    finally:
        learner.close()  # a batch in flight: the workers are stopped, not waited for
    assert learner.collection is None
    assert not any(p.is_alive() for p in procs)


@pytest.mark.parametrize("workers", [1, 2])
def test_the_noise_a_run_explores_with_is_correlated_as_its_recipe_says(tmp_path: Path, workers: int) -> None:
    """``noise_corr_s`` 0.2 s: each robot's noise (its action less its mean, in stds) is correlated
    ``exp(-0.02 / 0.2)`` = 0.90 from one control step to the next across iterations, and afresh after an episode
    ends; the default is white."""
    for corr_s, expected in ((0.2, np.exp(-0.02 / 0.2)), (0.0, 0.0)):
        learner = WalkerLearner(_run(tmp_path / f"{corr_s}", workers, noise_corr_s=corr_s))
        try:
            std = learner.ppo.net.log_std.detach().exp()
            rollouts = [learner.collect()[0] for _ in range(6)]  # no update: one actor, one std
        finally:
            learner.close()
        eps = torch.cat([(r.actions - r.means) / std for r in rollouts]).numpy()  # [T, N, joints]
        dones = torch.cat([r.dones for r in rollouts]).numpy()[:-1].astype(bool)  # step t ended an episode
        now, before = eps[1:], eps[:-1]
        assert dones.sum() >= 6
        within = np.corrcoef(now[~dones].ravel(), before[~dones].ravel())[0, 1]
        across = np.corrcoef(now[dones].ravel(), before[dones].ravel())[0, 1]
        assert within == pytest.approx(expected, abs=0.03)
        assert abs(across) < 0.25
