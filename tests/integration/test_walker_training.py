"""The mujoco backend's CPU trainer of the card robots (mujoco/walker_*.py, locomotion/learning.py).

- the actor started from an ONNX walker acts exactly as the ONNX before any update;
- episodes start at random points of the course (legs, dwells, elapsed time) and, from the start,
  span the whole course with its dwells; the runaway rule ends a training episode as a fall;
- the minibatch size is the recipe's, the learning rate follows the KL, the anchor holds the reference;
- one J: an episode's economic step rewards sum to the J its report scores it by (divided by the gain),
  on the report's own path (the meter's summary of the episode's raw metrics, ``objective_j``);
- a tiny fine-tune end to end on the CLI: train (from the shipped G1 PPO), export in Holosoma's format,
  price the export beside the shipped walker with ``compare``; a run resumes from its checkpoint.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch

from econmotor.config.objective_profile import ObjectiveVector
from econmotor.couriers.onnx_actor import policy_file, read_actor
from econmotor.couriers.policy_import import batched_onnx_policy, resolve_contract
from econmotor.locomotion import course as crs
from econmotor.locomotion.env import WalkerBatch
from econmotor.locomotion.learning import PRIVILEGED_DIM, WalkerLearningEnv, nominal_length_s, start_point
from econmotor.locomotion.model import WalkerModel
from econmotor.locomotion.stress import Stress
from econmotor.locomotion.task import MeterSettings
from econmotor.motor_backend.mujoco.walker_ppo import ActorCritic, Rollout, WalkerPPO
from econmotor.motor_backend.mujoco.walker_recipe import WalkerPPOConfig
from econmotor.motor_backend.results import summarize_episodes
from econmotor.objectives.loader import objective_from_vector, objective_j
from econmotor.tasks import get_task

METER = MeterSettings(leg_distance_m=2.0, drivetrain_efficiency=0.8, idle_power_w=50.0, tilt_margin_rad=0.2,
                      fall_tilt_rad=0.8)
SHORT = crs.CourseSettings(leg_m=2.0, dwell_s=1.0, speed_m_per_s=0.8, legs=2)
WEIGHTS = {"tracking_lin_vel": 2.0, "tracking_ang_vel": 1.5, "penalty_orientation": -10.0, "alive": 1.0}
OBJECTIVE = objective_from_vector(ObjectiveVector.from_preset("energy_saver"), "energy_saver")
ECONOMICS = get_task("humanoid_locomotion_g1").economics


@pytest.fixture(scope="module")
def g1_ppo():
    return resolve_contract("holosoma:g1_29dof/ppo")


def _env(contract, n: int, course: crs.CourseSettings = SHORT, random_start: bool = True, episode_s: float = 30.0,
         stress: Stress | None = None, pace: str = "course") -> WalkerLearningEnv:
    walker = WalkerModel.build(contract.card, np.asarray(contract.kp), np.asarray(contract.kd))
    batch = WalkerBatch(walker, course, METER, stress or Stress(), episode_s, n, contract.command_ranges)
    return WalkerLearningEnv(batch, OBJECTIVE, ECONOMICS, 2.0, WEIGHTS, seed=5, random_start=random_start, pace=pace)


@pytest.mark.parametrize("policy", ["holosoma:g1_29dof/ppo", "holosoma:t1_29dof/ppo"])
def test_initialised_actor_acts_as_the_onnx(policy: str) -> None:
    actor = read_actor(policy_file(policy))
    net = ActorCritic.from_actor(actor, PRIVILEGED_DIM, WalkerPPOConfig())
    learner = WalkerPPO(net, WalkerPPOConfig())
    contract = resolve_contract(policy)
    env = _env(contract, 4)
    obs, _ = env.reset()
    onnx = batched_onnx_policy(contract)
    for _ in range(5):  # a few steps of real walking observations
        np.testing.assert_allclose(learner.mean_action(obs), onnx(obs), atol=2e-5)
        obs = env.step(onnx(obs)).obs
    env.close()


def test_start_points_cover_the_course() -> None:
    rng = np.random.default_rng(0)
    points = [start_point(SHORT, rng, 0.02, 1500) for _ in range(400)]
    legs = {int(s.leg) for _, s, _ in points}
    dwelling = [p for p in points if p[1].dwell_left_s > 0]
    walking = [p for p in points if p[1].dwell_left_s == 0]
    assert legs == {0, 1}
    # the dwell's share of a leg's nominal time: 1 s of 2 / 0.8 + 1 = 3.5 s
    assert 0.2 < len(dwelling) / len(points) < 0.38
    for x, s, elapsed in dwelling:  # at the leg's end, the leg counted, time spent walking it and part of the dwell
        assert x == pytest.approx((s.leg + 1) * SHORT.leg_m) and s.legs_done == s.leg + 1
        assert 0.0 < s.dwell_left_s <= SHORT.dwell_s
        assert elapsed * 0.02 == pytest.approx(s.leg * 3.5 + 2.5 + 1.0 - s.dwell_left_s, abs=0.02)
    for x, s, elapsed in walking:
        assert s.leg * SHORT.leg_m <= x < (s.leg + 1) * SHORT.leg_m and s.legs_done == s.leg
        assert elapsed * 0.02 == pytest.approx(s.leg * 3.5 + (x - s.leg * SHORT.leg_m) / 0.8, abs=0.02)


def test_random_starts_place_robots_and_meter_from_there(g1_ppo) -> None:
    env = _env(g1_ppo, 8)
    env.reset()
    b = env.batch
    x = b._qpos(b.state)[:, 0]
    assert len(np.unique(np.round(x, 3))) > 3  # robots placed along the course
    np.testing.assert_allclose(b.sums.best_x, x)  # the meter's high-water mark starts where the robot stands
    assert (b.steps > 0).any()  # and the time the course took so far counts against the limit
    for s in range(b.n):
        d = b.datas[s]
        assert d.qpos[0] == pytest.approx(x[s])  # the physics moved, not only the record
    env.close()


def test_a_training_episode_from_the_start_spans_the_course(g1_ppo) -> None:
    env = _env(g1_ppo, 2, random_start=False)
    obs, _ = env.reset()
    policy = batched_onnx_policy(g1_ppo)
    episodes, truncated = [], 0
    for _ in range(1500):
        out = env.step(policy(obs))
        obs = out.obs
        truncated += int(out.truncated.sum())
        episodes += out.episodes
        if episodes:
            break
    assert episodes, "no episode ended in 30 s of a 2-leg course"
    ep = episodes[0]
    assert ep["legs_reached"] == SHORT.legs and ep["termination_reason"] == "course_done"
    # both legs walked and both dwells stood: at least the legs at the command's speed plus the dwells
    assert ep["episode_length_s"] >= SHORT.legs * (SHORT.leg_m / SHORT.speed_m_per_s + SHORT.dwell_s) * 0.9
    assert truncated >= 1  # the course's end truncates (bootstrapped), it does not terminate
    env.close()


def test_runaway_ends_a_training_episode_as_a_fall(g1_ppo) -> None:
    env = _env(g1_ppo, 2, random_start=False)
    env.weights = {}  # the economic part only
    obs, _ = env.reset()
    b = env.batch
    qvel = b._qvel(b.state[0])
    qvel[0] = 50.0  # a blow-up: the base at 50 m/s, upright
    b.load_state(np.array([0]))
    out = env.step(batched_onnx_policy(g1_ppo)(obs))
    assert out.terminated[0] and not out.truncated[0]
    assert out.episodes[0]["errors"] == 1.0
    # the fall's price reached the learner: its one-step episode's J, whose safety term (a catastrophic end)
    # and error rate a fall-free episode of the same steps does not pay
    fell = out.episodes[0]
    upright = {**fell, "errors": 0.0, "units_attempted": fell["units_completed"], "termination_reason": "max_steps"}
    assert out.reward[0] / env.gain == pytest.approx(_report_j(fell), rel=1e-9)
    assert _report_j(fell) < _report_j(upright) - 0.9 * (OBJECTIVE.risk_weight + OBJECTIVE.error_weight)
    env.close()


def _report_j(raw_episode: dict) -> float:
    """The episode's J as a report scores it: the meter's summary of its raw metrics, then ``objective_j``."""
    [summary] = summarize_episodes([raw_episode], ECONOMICS)[2]
    return objective_j(OBJECTIVE, summary, ECONOMICS)


@pytest.mark.parametrize(("random_start", "pace"), [(False, "course"), (True, "course"), (True, "walker")])
def test_one_j_an_episodes_economic_rewards_sum_to_its_reported_j(g1_ppo, random_start: bool, pace: str) -> None:
    env = _env(g1_ppo, 2, random_start=random_start, episode_s=6.0, pace=pace)
    env.weights = {}  # the economic part only
    obs, _ = env.reset()
    policy = batched_onnx_policy(g1_ppo)
    total, ended = np.zeros(2), []
    while len(ended) < 3:
        out = env.step(policy(obs))
        obs, total = out.obs, total + out.reward
        done = np.flatnonzero(out.terminated | out.truncated)
        for row, episode in zip(done, out.episodes, strict=True):
            ended.append((total[row] / env.gain, _report_j(episode), episode))
            total[row] = 0.0
    assert any(episode["units_completed"] > 0.1 for *_, episode in ended)  # they walked ...
    for summed, reported, episode in ended:
        assert episode["energy_wh"] > 0  # ... and drew power
        assert summed == pytest.approx(reported, rel=1e-9, abs=1e-9)
    env.close()


def test_one_j_pays_each_leg_when_it_is_walked(g1_ppo) -> None:
    """Before its last step an episode is paid its J's terms as they accrue, rates over its nominal length
    (the course left at the course's speed): a leg walked at any time earns the same, and the first steps of
    an episode no more than their legs and Wh (the running rate's increments pay them its whole J at once)."""
    env = _env(g1_ppo, 2, random_start=False)
    env.weights = {}
    obs, _ = env.reset()
    nominal = SHORT.legs * (SHORT.leg_m / SHORT.speed_m_per_s + SHORT.dwell_s)
    assert nominal_length_s(SHORT, 30.0) == pytest.approx(nominal)
    assert nominal_length_s(SHORT, 4.0) == pytest.approx(4.0)  # within the time limit
    policy, sums = batched_onnx_policy(g1_ppo), env.batch.sums
    walked = 0.0
    for _ in range(100):
        units, wh = sums.units[:2].copy(), sums.energy_wh[:2].copy()
        out = env.step(policy(obs))
        obs = out.obs
        assert not (out.terminated | out.truncated).any()
        expected = OBJECTIVE.mpl_weight * 3600.0 * (sums.units[:2] - units) / nominal \
            - OBJECTIVE.energy_weight * (sums.energy_wh[:2] - wh)
        np.testing.assert_allclose(out.reward / env.gain, expected, rtol=1e-9, atol=1e-12)
        walked += float((sums.units[:2] - units).sum())
    assert walked > 0.05
    env.close()


def test_the_nominal_length_is_the_course_left_at_a_pace() -> None:
    """``T`` from a point of the course: the distance left at the pace, the dwells left stood; at the course's
    speed it is the nominal time the course had left where the start point counted the time already spent."""
    walk_s, dwell_s = SHORT.leg_m / SHORT.speed_m_per_s, SHORT.dwell_s
    assert nominal_length_s(SHORT, 99.0, x_m=1.0) == pytest.approx(3.0 / 0.8 + 2 * dwell_s)  # half-way along leg 0
    assert nominal_length_s(SHORT, 99.0, x_m=2.0, legs_done=1.0, dwell_left_s=0.4) == pytest.approx(
        0.4 + walk_s + dwell_s)  # in leg 0's dwell
    assert nominal_length_s(SHORT, 99.0, x_m=1.0, speed_m_per_s=0.5) == pytest.approx(3.0 / 0.5 + 2 * dwell_s)
    rng = np.random.default_rng(3)
    whole_s = SHORT.legs * (walk_s + dwell_s)
    for _ in range(50):
        x, state, elapsed = start_point(SHORT, rng, 0.02, 1500)
        assert nominal_length_s(SHORT, 30.0 - elapsed * 0.02, x, state.legs_done, state.dwell_left_s) == \
            pytest.approx(whole_s - elapsed * 0.02, abs=0.021)  # the start point's elapsed steps are floored


def test_under_the_walkers_pace_t_follows_its_finished_episodes(g1_ppo) -> None:
    """``pace="walker"``: the speed ``T`` is taken at moves from the course's toward the walking speed of the
    episodes that ended, and the next episodes' ``T`` is taken at it (a walker slower than the command: longer)."""
    env = _env(g1_ppo, 2, random_start=False, pace="walker")
    obs, _ = env.reset()
    policy, speeds = batched_onnx_policy(g1_ppo), []
    start_t = float(env._length_s[0])
    assert env.pace_m_per_s == SHORT.speed_m_per_s
    for _ in range(1500):
        out = env.step(policy(obs))
        obs = out.obs
        speeds += [ep["achieved_speed_m_per_s"] for ep in out.episodes]
        if speeds:
            break
    assert speeds and speeds[0] < SHORT.speed_m_per_s  # the shipped walker under-tracks the command
    expected = SHORT.speed_m_per_s
    for speed in speeds:  # an exponential average, in the order the episodes ended
        expected += 0.1 * (speed - expected)
    assert env.pace_m_per_s == pytest.approx(expected)
    assert out.terms["pace_m_per_s"] == SHORT.speed_m_per_s  # the pace this step was paid at
    restarted = int(np.flatnonzero(out.truncated | out.terminated)[-1])  # started after the last update
    assert env._length_s[restarted] == pytest.approx(nominal_length_s(SHORT, 30.0, speed_m_per_s=env.pace_m_per_s))
    assert env._length_s[restarted] > start_t
    with pytest.raises(ValueError, match="pace"):
        _env(g1_ppo, 2, pace="fast")
    env.close()


def test_one_j_a_fall_is_paid_as_the_report_scores_it(g1_ppo) -> None:
    env = _env(g1_ppo, 2, random_start=False)
    env.weights = {}
    obs, _ = env.reset()
    policy = batched_onnx_policy(g1_ppo)
    total = np.zeros(2)
    for _ in range(20):
        out = env.step(policy(obs))
        obs, total = out.obs, total + out.reward
    b = env.batch
    b._qvel(b.state[0])[0] = 50.0  # robot 0 blows up: a fall
    b.load_state(np.array([0]))
    out = env.step(policy(obs))
    assert out.terminated[0]
    summed = (total[0] + out.reward[0]) / env.gain
    assert summed == pytest.approx(_report_j(out.episodes[0]), rel=1e-9)
    assert out.episodes[0]["termination_reason"] == "fall"
    env.close()


def _rollout(cfg: WalkerPPOConfig, obs_dim: int, act_dim: int, seed: int = 0) -> tuple[Rollout, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    t, n = cfg.steps_per_iteration, cfg.num_envs
    mean = torch.randn(t, n, act_dim, generator=g) * 0.1
    actions = mean + 0.1 * torch.randn(t, n, act_dim, generator=g)
    logp = torch.distributions.Normal(mean, 0.1).log_prob(actions).sum(-1)
    priv = torch.randn(t, n, PRIVILEGED_DIM, generator=g)
    return Rollout(obs=torch.randn(t, n, obs_dim, generator=g), privileged=priv,
                   actions=actions, log_probs=logp, means=mean, values=torch.zeros(t, n),
                   rewards=torch.randn(t, n, generator=g), dones=torch.zeros(t, n)), torch.zeros(n)


def test_minibatches_are_the_recipes() -> None:
    cfg = WalkerPPOConfig.from_mapping({"num_envs": 8, "steps_per_iteration": 32, "num_minibatches": 4,
                                        "num_epochs": 3, "critic_warmup_iterations": 0, "hidden_sizes": [16],
                                        "critic_hidden_sizes": [16]})
    assert cfg.minibatch_size == 64
    learner = WalkerPPO(ActorCritic(10, PRIVILEGED_DIM, 3, cfg), cfg)
    seen: list[int] = []
    learner.net.critic.register_forward_hook(lambda m, i, o: seen.append(i[0].shape[0]))
    learner.update(*_rollout(cfg, 10, 3))
    assert seen == [64] * 12  # 3 epochs x 4 minibatches of 64, every sample once an epoch


def test_learning_rate_follows_the_kl_and_warmup_moves_only_the_critic() -> None:
    cfg = WalkerPPOConfig.from_mapping({"num_envs": 8, "steps_per_iteration": 32, "critic_warmup_iterations": 1,
                                        "hidden_sizes": [16], "critic_hidden_sizes": [16], "learning_rate": 1e-4})
    learner = WalkerPPO(ActorCritic(10, PRIVILEGED_DIM, 3, cfg), cfg)
    actor_before = [p.detach().clone() for p in learner.net.actor.parameters()]
    stats = learner.update(*_rollout(cfg, 10, 3))
    assert stats["critic_warmup"] == 1.0 and learner.learning_rate == 1e-4
    assert all(torch.equal(a, b) for a, b in zip(actor_before, learner.net.actor.parameters(), strict=True))
    learner._adapt(1.0)  # far above 2 x desired: divided by 1.5
    assert learner.learning_rate == pytest.approx(1e-4 / 1.5)
    learner._adapt(0.0)  # below half: multiplied by 1.5
    assert learner.learning_rate == pytest.approx(1e-4)
    assert learner.optimizer.param_groups[0]["lr"] == pytest.approx(1e-4)
    learner.update(*_rollout(cfg, 10, 3, seed=1))
    assert any(not torch.equal(a, b) for a, b in zip(actor_before, learner.net.actor.parameters(), strict=True))
    # in an update the rate follows the KL it measures: any step is far above a target of 1e-9, so it falls
    strict = WalkerPPOConfig.from_mapping({**cfg.to_dict(), "critic_warmup_iterations": 0, "desired_kl": 1e-9})
    tight = WalkerPPO(ActorCritic(10, PRIVILEGED_DIM, 3, strict), strict)
    stats = tight.update(*_rollout(strict, 10, 3, seed=2))
    assert stats["kl"] > 2e-9 and tight.learning_rate < 1e-4
    assert tight.optimizer.param_groups[0]["lr"] == pytest.approx(tight.learning_rate)


def test_the_anchor_pulls_towards_the_reference() -> None:
    base = {"num_envs": 8, "steps_per_iteration": 32, "critic_warmup_iterations": 0, "hidden_sizes": [16],
            "critic_hidden_sizes": [16], "learning_rate": 1e-3, "lr_bounds": [1e-3, 1e-3], "num_epochs": 8}
    drift = {}
    for coef in (0.0, 50.0):
        torch.manual_seed(0)
        cfg = WalkerPPOConfig.from_mapping({**base, "anchor_coef": coef})
        learner = WalkerPPO(ActorCritic(10, PRIVILEGED_DIM, 3, cfg), cfg)
        reference = [p.detach().clone() for p in learner.net.actor.parameters()]
        for i in range(3):
            learner.update(*_rollout(cfg, 10, 3, seed=i))
        now = learner.net.actor.parameters()
        drift[coef] = sum((a - b).detach().square().sum().item() for a, b in zip(reference, now, strict=True))
    assert drift[50.0] < drift[0.0]


def test_recipe_errors_name_the_key() -> None:
    from econmotor.errors import ConfigError

    with pytest.raises(ConfigError, match="num_minibatches"):
        WalkerPPOConfig.from_mapping({"num_envs": 3, "steps_per_iteration": 5, "num_minibatches": 2})
    with pytest.raises(ConfigError, match="minibatch"):
        WalkerPPOConfig.from_mapping({"minibatch": 3})


def test_tiny_fine_tune_end_to_end(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """train (CLI) from the shipped G1 PPO -> policy.onnx in Holosoma's format -> compare beside the shipped walker;
    then the run resumes from its checkpoint to a larger budget."""
    from econmotor.cli import main

    run = tmp_path / "run"
    db = f"sqlite:///{tmp_path / 'reg.db'}"
    train = ["train", "--motor-backend", "mujoco", "--task-id", "humanoid_locomotion_g1", "--objective-preset",
             "energy_saver", "--num-envs", "4", "--select-every", "0", "--output-dir", str(run), "--db-url", db]
    assert main([*train, "--init-policy", "holosoma:g1_29dof/ppo", "--max-steps", "200", "--eval-episodes", "2"]) == 0
    assert "humanoid_locomotion_g1 on mujoco" in capsys.readouterr().out
    config = json.loads((run / "run_config.json").read_text())
    assert config["trainer"] == "walker" and config["init_policy"]["policy"] == "holosoma:g1_29dof/ppo"
    per_iteration = 4 * config["hyperparameters"]["steps_per_iteration"]  # --num-envs 4 x the catalog's steps
    assert config["hyperparameters"]["num_envs"] == 4
    assert config["trained_steps"] == per_iteration  # one iteration: the first past 200
    assert main(["report", "--motor-backend", "none", "--task-id", "humanoid_locomotion_g1", "--run-id", "1",
                 "--db-url", db, "--output-dir", str(tmp_path / "report")]) == 0
    document = json.loads((tmp_path / "report" / "humanoid_locomotion_g1_run1.json").read_text())
    seen = document["learned_with"]  # the report says what the learner saw
    assert seen["econ_gain"] == config["econ_gain"]
    assert seen["objective_weights"] == {"r_mpl": 1.0, "r_error": 1.0, "r_energy": 3.0, "r_safety": 1.0,
                                         "r_novelty": 0.0}  # energy_saver's: the report's J is the learner's
    assert seen["per_wh"] == pytest.approx(-3.0 * config["econ_gain"]) and "tracking_lin_vel" in seen["locomotion"]
    assert document["started_from"]["policy"] == "holosoma:g1_29dof/ppo"
    assert "learned with" in (tmp_path / "report" / "humanoid_locomotion_g1_run1.md").read_text()
    exported = read_actor(run / "policy.onnx")
    assert exported.input_name == "actor_obs" and exported.hidden_sizes == (512, 256, 128)
    assert resolve_contract(str(run / "policy.onnx")).card.name == "g1_29dof"
    assert main(["compare", "--task-id", "humanoid_locomotion_g1", "--policy", str(run / "policy.onnx"),
                 "--policy", "holosoma:g1_29dof/ppo", "--eval-episodes", "2", "--db-url", db,
                 "--output-dir", str(tmp_path / "cmp")]) == 0
    result = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert len(json.dumps(result)) > 0 and str(run / "policy.onnx") in json.dumps(result)


def test_an_interrupted_run_resumes_from_its_checkpoint(tmp_path: Path) -> None:
    from econmotor.config.objective_profile import ObjectiveVector
    from econmotor.motor_backend.mujoco.backend import MujocoBackend
    from econmotor.objectives.loader import objective_from_vector

    objective = objective_from_vector(ObjectiveVector.from_preset("throughput"), "throughput")
    backend = MujocoBackend(runs_dir=tmp_path)
    iterations = []

    def interrupt_at_the_second(message: str, done: float, total: float) -> None:
        if " steps, " in message:
            iterations.append(message)
            if len(iterations) == 2:
                raise KeyboardInterrupt

    run = tmp_path / "run"
    kwargs = {"num_envs": 4, "seed": 3, "output_dir": run, "select_every_steps": 0, "eval_episodes": 0}
    with pytest.raises(KeyboardInterrupt):
        backend.train_policy("humanoid_locomotion_g1", objective, [], max_steps=10**6,
                             init_policy="holosoma:g1_29dof/ppo", progress=interrupt_at_the_second, **kwargs)
    assert not backend.is_complete_run(run)
    per_iteration = 4 * json.loads((run / "run_config.json").read_text())["hyperparameters"]["steps_per_iteration"]
    result = backend.train_policy("humanoid_locomotion_g1", objective, [], max_steps=3 * per_iteration, resume=True,
                                  **kwargs)
    rows = [json.loads(line) for line in (run / "curve.jsonl").read_text().splitlines()]
    assert [r["iteration"] for r in rows] == [1, 2, 3]  # the two before the interruption, then one more
    assert result.config["trained_steps"] == 3 * per_iteration and backend.is_complete_run(run)
    assert result.config["init_policy"]["policy"] == "holosoma:g1_29dof/ppo"


def _g1_episode(legs: float, fell: bool) -> dict:
    """One priced G1 course episode's raw metrics (a fall ends it and counts as an attempted leg)."""
    return {"units_completed": legs, "units_attempted": legs + (1.0 if fell else 0.0), "errors": 1.0 if fell else 0.0,
            "episode_length_s": 240.0, "energy_wh": 6.0, "risk_score": 0.0, "novelty_score": 0.0,
            "return": 10.0 * legs, "length_steps": 12_000.0, "termination_reason": "fall" if fell else "max_steps"}


def test_the_walker_run_keeps_the_mid_run_policy_its_evaluations_selected(tmp_path: Path,
                                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Held-out evaluations scripted as falling (the shipped walker it starts from, judged first at env step 0,
    and the first checkpoint), then safe (acceptable), then fast but falling (the highest J, not acceptable): the
    run's policy.onnx is the actor the third evaluation saw, not the start's or the last."""
    from econmotor.motor_backend.mujoco import walker_training
    from econmotor.motor_backend.mujoco.backend import MujocoBackend
    from econmotor.objectives import EconomicObjectiveSpec

    episodes = 80
    script = ([_g1_episode(2.0, i % 2 == 0) for i in range(episodes)],
              [_g1_episode(2.0, i % 2 == 0) for i in range(episodes)], [_g1_episode(6.0, False)] * episodes,
              [_g1_episode(9.0, i % 3 == 0) for i in range(episodes)])
    seen: list[list[np.ndarray]] = []

    def scripted(self, learner, num_episodes, first_seed, stop):
        seen.append([layer["w"].copy() for layer in learner.net.layers()])
        rows = script[len(seen) - 1][:num_episodes]
        for done in range(16, len(rows) + 16, 16):  # asked after every batch, as the walker batch does
            if stop(rows[:done]):
                return rows[:done]
        return rows

    monkeypatch.setattr(walker_training.WalkerTrainingRun, "evaluate", scripted)
    per_iteration = 2 * 16
    result = MujocoBackend(runs_dir=tmp_path).train_policy(
        "humanoid_locomotion_g1", EconomicObjectiveSpec(), [], num_envs=2, max_steps=3 * per_iteration, seed=4,
        output_dir=tmp_path / "run", init_policy="holosoma:g1_29dof/ppo", eval_episodes=0,
        select_every_steps=per_iteration, select_episodes=episodes,
        hyperparameters={"steps_per_iteration": 16, "num_minibatches": 1, "critic_warmup_iterations": 0,
                         "learning_rate": 1e-3})
    assert len(seen) == 4 and not np.array_equal(seen[2][0], seen[3][0])  # PPO moved between the evaluations
    record = result.config["selection"]
    assert [(e["env_steps"], e["deployable"]) for e in record["evaluations"]] == [
        (0, False), (per_iteration, False), (2 * per_iteration, True), (3 * per_iteration, False)]
    assert record["kept"]["env_steps"] == 2 * per_iteration
    kept = read_actor(tmp_path / "run" / "policy.onnx")
    for layer, weights in zip(kept.layers, seen[2], strict=True):
        np.testing.assert_allclose(layer["w"], weights, rtol=0, atol=1e-6,
                                   err_msg="policy.onnx is not the actor the held-out evaluations selected")
