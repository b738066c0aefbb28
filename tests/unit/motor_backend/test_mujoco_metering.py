"""EconomicMeteringWrapper (the meter and the objective overlay) on real Gymnasium MuJoCo envs."""

import gymnasium as gym
import numpy as np
import pytest

from econmotor.couriers.overlay import TERM_METRICS
from econmotor.economics.courier_formulas import episode_metric
from econmotor.errors import ConfigError, UnknownNameError
from econmotor.motor_backend.mujoco.backend import MujocoBackend
from econmotor.motor_backend.mujoco.metering import EconomicMeteringWrapper, VisitNovelty
from econmotor.motor_backend.mujoco.settings import parse_mujoco_settings
from econmotor.objectives import EconomicObjectiveSpec
from econmotor.tasks import load_catalog


def run_episode(env, seed, policy=None, max_steps=10_000):
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    rewards, infos = [], []
    for _ in range(max_steps):
        action = policy(obs) if policy else rng.uniform(-1, 1, env.action_space.shape)
        obs, reward, terminated, truncated, info = env.step(action)
        rewards.append(reward)
        infos.append(info)
        if terminated or truncated:
            return rewards, infos, terminated
    raise AssertionError("episode did not end")


def test_catalog_ships_four_couriers_with_sourced_economics():
    catalog = load_catalog()
    expected = {"hopper_courier": "Hopper-v5", "walker_courier": "Walker2d-v5", "ant_courier": "Ant-v5",
                "humanoid_courier": "Humanoid-v5"}
    for task_id, env_id in expected.items():
        spec = catalog.get(task_id)
        assert parse_mujoco_settings(spec).env_id == env_id
        assert "leg" in spec.unit and "fall" in spec.error_definition and "error rate" in spec.error_definition
        for row in spec.economics.parameters():
            assert row["source"] and row["source"] != "econmotor default", (task_id, row["name"])
    assert parse_mujoco_settings(catalog.get("hopper_courier")).algorithm == "ppo"


def test_unknown_task_lists_known_ones():
    with pytest.raises(UnknownNameError, match="hopper_courier"):
        MujocoBackend().task("hoper_courier")


def test_meter_reports_energy_from_actuator_forces_and_a_fall_as_one_error():
    env = EconomicMeteringWrapper(gym.make("Hopper-v5"), leg_distance_m=1.0, drivetrain_efficiency=0.5,
                                  idle_power_w=10.0, tilt_margin_rad=0.1, fall_tilt_rad=0.2)
    env.reset(seed=0)
    data, expected_wh = env.unwrapped.data, 0.0
    best_x = x0 = float(data.qpos[0])
    rng = np.random.default_rng(0)
    while True:
        _, _, terminated, truncated, info = env.step(rng.uniform(-1, 1, 3))
        mech_w = float(np.sum(np.abs(data.qfrc_actuator[3:] * data.qvel[3:])))  # hopper's actuated hinges
        expected_wh += (mech_w / 0.5 + 10.0) * env.unwrapped.dt / 3600
        best_x = max(best_x, float(data.qpos[0]))
        if terminated or truncated:
            break
    raw = info["econ_episode"]
    assert terminated and raw["termination_reason"] == "fall" and raw["errors"] == 1.0
    assert raw["energy_wh"] == pytest.approx(expected_wh, rel=1e-9)
    # power must reflect joint torques after the gear (200x actuator_force on Hopper), not idle power alone
    assert raw["energy_wh"] > 2 * 10.0 * raw["episode_length_s"] / 3600
    assert raw["units_completed"] == pytest.approx(best_x - x0)
    assert raw["units_attempted"] == pytest.approx(raw["units_completed"] + 1.0)
    assert 0.0 < raw["risk_score"] <= 1.0 and 0.0 < raw["novelty_score"] <= 1.0


def test_truncated_episode_ends_with_max_steps_and_no_error():
    env = EconomicMeteringWrapper(gym.make("Hopper-v5", max_episode_steps=20))
    _, infos, terminated = run_episode(env, 1, policy=lambda obs: np.zeros(3))
    raw = infos[-1]["econ_episode"]
    assert not terminated and raw["termination_reason"] == "max_steps" and raw["errors"] == 0.0
    assert raw["length_steps"] == 20 and raw["episode_length_s"] == pytest.approx(20 * 0.008)


@pytest.mark.parametrize("env_id", ["Hopper-v5", "Ant-v5"])
def test_each_overlay_term_sums_to_its_episode_metric(env_id):
    scales = {key: 0.5 + i for i, key in enumerate(k for k in TERM_METRICS if k != "pose_tracking")}
    refs = {"mpl_per_hour": 468.0, "error_rate": 0.002, "energy_kwh": 4e-5}
    env = EconomicMeteringWrapper(gym.make(env_id, max_episode_steps=60), leg_distance_m=0.05, scales=scales,
                                  keep_task_reward=True, references=refs)
    task_env = EconomicMeteringWrapper(gym.make(env_id, max_episode_steps=60), leg_distance_m=0.05)
    progressed = []
    for seed in range(4):
        rewards, infos, _ = run_episode(env, seed)
        task_rewards, _, _ = run_episode(task_env, seed)
        raw, terms = infos[-1]["econ_episode"], infos[-1]["overlay_terms"]
        for key, scale in scales.items():
            assert terms[key]["raw"] == pytest.approx(episode_metric(raw, key), rel=1e-9, abs=1e-12), key
            weighted = scale * episode_metric(raw, key) / refs.get(key, 1.0)
            assert terms[key]["weighted"] == pytest.approx(weighted, rel=1e-9, abs=1e-12)
        overlay_return = sum(scale * episode_metric(raw, k) / refs.get(k, 1.0) for k, scale in scales.items())
        assert sum(rewards) == pytest.approx(sum(task_rewards) + overlay_return, rel=1e-9)
        progressed.append(raw["units_completed"] > 0)
        sums = env.episode  # the one-call snapshot agrees with the named running metrics
        assert sums.running_metrics() == tuple(getattr(sums, key)() for key in TERM_METRICS)
    assert any(progressed)  # the mpl and error terms were exercised with non-zero units


def test_overlay_can_replace_the_task_reward_and_rejects_unknown_terms():
    env = EconomicMeteringWrapper(gym.make("Hopper-v5", max_episode_steps=30), scales={"energy_kwh": -2.0},
                                  keep_task_reward=False)
    rewards, infos, _ = run_episode(env, 0)
    assert sum(rewards) == pytest.approx(-2.0 * infos[-1]["econ_episode"]["energy_wh"] / 1000.0)
    with pytest.raises(ConfigError, match="stability_margin"):
        EconomicMeteringWrapper(gym.make("Hopper-v5"), scales={"stability_margin": -0.1})
    with pytest.raises(ConfigError, match=r"references\.energy_kwh"):
        EconomicMeteringWrapper(gym.make("Hopper-v5"), scales={"energy_kwh": -2.0}, references={"energy_kwh": 0.0})


def test_without_scales_the_reward_is_the_envs_own():
    raw, meter = gym.make("Hopper-v5", max_episode_steps=40), EconomicMeteringWrapper(gym.make("Hopper-v5",
                                                                                             max_episode_steps=40))
    raw_rewards, _, _ = run_episode(raw, 2)
    rewards, infos, _ = run_episode(meter, 2)
    assert rewards == raw_rewards
    assert infos[-1]["econ_episode"]["return"] == pytest.approx(sum(raw_rewards), rel=1e-12)
    assert "overlay_terms" not in infos[-1] and "overlay_return" not in infos[-1]


@pytest.mark.parametrize("task_id", ["hopper_courier", "walker_courier", "ant_courier", "humanoid_courier"])
def test_every_courier_builds_its_metered_env(task_id):
    from econmotor.motor_backend.mujoco.env_factory import make_env

    recipe, described = MujocoBackend().recipe(task_id, EconomicObjectiveSpec(mpl_weight=1.0, error_weight=1.0))
    env = make_env(recipe, seed=0)
    rewards, infos, _ = run_episode(env, 0, max_steps=2000)
    raw = infos[-1]["econ_episode"]
    assert raw["energy_wh"] > 0 and raw["length_steps"] == len(rewards)
    assert described["overlay_references"] == {"mpl_per_hour": 468.0, "error_rate": 0.002}


@pytest.mark.parametrize("novelty_weight", [0.0, 0.5])
def test_training_envs_meter_novelty_only_where_the_overlay_rewards_it(novelty_weight):
    """An evaluation's env always meters novelty; a training env only when the overlay has a novelty
    term, and then with the same reward as the evaluation's env on the same episode."""
    from econmotor.motor_backend.mujoco.env_factory import make_env

    spec = EconomicObjectiveSpec(mpl_weight=1.0, error_weight=1.0, novelty_weight=novelty_weight)
    recipe, _ = MujocoBackend().recipe("hopper_courier", spec)
    eval_rewards, eval_infos, _ = run_episode(make_env(recipe, seed=0), 3)
    train_env = make_env(recipe, seed=0, training=True)
    train_rewards, train_infos, _ = run_episode(train_env, 3)
    assert eval_infos[-1]["econ_episode"]["novelty_score"] > 0
    rewarded = "novelty_score" in recipe.scales
    assert rewarded == (novelty_weight > 0)
    assert ("novelty_score" in train_infos[-1]["econ_episode"]) == rewarded
    assert bool(train_env.visit_counts) == rewarded
    assert train_rewards == eval_rewards


def reference_episode(env, seed, counts, tilt_margin, fall_tilt, novelty_bin=0.25, dims=5):
    """One episode through ``env`` (a bare meter) with energy, risk and novelty recomputed per step
    from MjData the plain way: power over *all* dofs, tilt via acos, visit counts in ``counts``."""
    base = env.unwrapped
    data, free_root = base.data, base.model.jnt_type[0] == 0  # mjJNT_FREE
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    wh = risk = novelty = 0.0
    while True:
        obs, _, terminated, truncated, info = env.step(rng.uniform(-0.4, 0.4, env.action_space.shape))
        wh += (float(np.sum(np.abs(data.qfrc_actuator * data.qvel))) / 0.6 + 20.0) * base.dt / 3600
        q = data.qpos
        tilt = (np.arccos(np.clip(1 - 2 * (q[4] ** 2 + q[5] ** 2), -1, 1)) if free_root else abs(q[2]))
        risk += float(np.clip((tilt - tilt_margin) / (fall_tilt - tilt_margin), 0, 1))
        cell = tuple(int(np.floor(v / novelty_bin)) for v in obs[:dims])
        counts[cell] = counts.get(cell, 0) + 1
        novelty += counts[cell] ** -0.5
        if terminated or truncated:
            steps = info["econ_episode"]["length_steps"]
            return info["econ_episode"], {"energy_wh": wh, "risk_score": risk / steps, "novelty_score": novelty / steps}


@pytest.mark.parametrize(("env_id", "span", "margin"), [("Hopper-v5", (3, 6), 0.05), ("Humanoid-v5", (6, 23), 0.1)])
def test_meter_matches_a_plain_per_step_recomputation(env_id, span, margin):
    """Energy over the actuated dof span, risk and novelty agree with the plain per-step formulas,
    over episodes sharing visit counts."""
    from econmotor.motor_backend.mujoco.metering import actuated_dof_span

    env = EconomicMeteringWrapper(gym.make(env_id, max_episode_steps=80), tilt_margin_rad=margin, fall_tilt_rad=0.5)
    assert actuated_dof_span(env.unwrapped.model) == span
    counts: dict = {}
    risky = False
    for seed in range(3):
        raw, expected = reference_episode(env, seed, counts, margin, 0.5)
        for key, value in expected.items():
            assert raw[key] == pytest.approx(value, rel=1e-9, abs=1e-15), (key, seed)
        risky |= raw["risk_score"] > 0
    assert risky  # the tilt branch past the margin ran
    assert env.visit_counts == counts


@pytest.mark.filterwarnings("ignore::UserWarning", "ignore::RuntimeWarning")  # gymnasium casting the Box
@pytest.mark.parametrize("dtype", [np.float32, np.int64])
def test_novelty_counts_observations_of_any_dtype(dtype):
    """float32 and int64 observations: the visit counts are those of flooring each step's obs[:5] / bin."""
    env = EconomicMeteringWrapper(gym.wrappers.DtypeObservation(gym.make("Hopper-v5", max_episode_steps=60), dtype))
    counts: dict = {}
    for seed in range(2):
        env.reset(seed=seed)
        rng, done = np.random.default_rng(seed), False
        while not done:
            obs, _, terminated, truncated, _ = env.step(rng.uniform(-0.4, 0.4, 3))
            assert obs.dtype == dtype
            cell = tuple(int(np.floor(float(v) / 0.25)) for v in obs[:5])
            counts[cell] = counts.get(cell, 0) + 1
            done = terminated or truncated
    assert env.visit_counts == counts and sum(counts.values()) > 10


def test_novelty_dims_beyond_the_observation_take_the_whole_observation():
    """novelty_dims = 20 on Hopper's 11-entry observation: the cells are those of all 11 entries."""
    env = EconomicMeteringWrapper(gym.make("Hopper-v5", max_episode_steps=30), novelty_dims=20)
    env.reset(seed=0)
    rng, counts, done = np.random.default_rng(0), {}, False
    while not done:
        obs, _, terminated, truncated, info = env.step(rng.uniform(-0.4, 0.4, 3))
        cell = tuple(int(np.floor(v / 0.25)) for v in obs)
        counts[cell] = counts.get(cell, 0) + 1
        done = terminated or truncated
    assert env.visit_counts == counts and all(len(cell) == 11 for cell in counts)
    assert info["econ_episode"]["novelty_score"] > 0


def test_overlay_step_reward_is_the_change_of_the_weighted_running_metrics():
    """Per step (not only summed): r_t - r_task_t = sum_k factor_k (m_k(t) - m_k(t-1))."""
    scales = {key: 0.5 + i for i, key in enumerate(k for k in TERM_METRICS if k != "pose_tracking")}
    refs = {"mpl_per_hour": 468.0, "error_rate": 0.002, "energy_kwh": 4e-5}
    env = EconomicMeteringWrapper(gym.make("Hopper-v5"), leg_distance_m=0.05, scales=scales, references=refs)
    steps = 0
    for seed in range(2):
        env.reset(seed=seed)
        rng, prev, prev_return, done = np.random.default_rng(seed), dict.fromkeys(scales, 0.0), 0.0, False
        while not done:
            _, reward, terminated, truncated, _ = env.step(rng.uniform(-1, 1, 3))
            sums = env.episode
            now = {k: getattr(sums, k)() for k in scales}
            expected = sum(s / refs.get(k, 1.0) * (now[k] - prev[k]) for k, s in scales.items())
            task_reward = sums.task_return - prev_return
            assert reward - task_reward == pytest.approx(expected, rel=1e-9, abs=1e-9)
            prev, prev_return, done, steps = now, sums.task_return, terminated or truncated, steps + 1
    assert steps > 10


def test_visits_score_the_inverse_square_root_of_their_count():
    """Cells repeated and revisited: visit n of a cell scores n ** -0.5, in the order of the points."""
    rng = np.random.default_rng(3)
    points = rng.uniform(-0.6, 0.6, (300, 7))  # 5 hashed dims at bin 0.25: many repeats
    points[10:20] = points[3]  # one cell ten more times
    novelty, counts, expected, got = VisitNovelty(0.25, dims=5), {}, 0.0, 0.0
    for p in (*points, *points[:40]):  # and the first 40 again
        cell = tuple(int(np.floor(v / 0.25)) for v in p[:5])
        counts[cell] = counts.get(cell, 0) + 1
        expected += counts[cell] ** -0.5
        got += novelty.visit(p)
    assert novelty.cells == counts
    assert max(counts.values()) >= 12
    assert got == pytest.approx(expected, rel=1e-12)


def test_a_non_finite_coordinate_counts_in_a_cell_of_its_own_read_back_as_index_none():
    """NaN and infinite coordinates count (NaN, -inf and +inf each in cells of their own); ``cells``
    reads their index back as None and adds up the cells that then look alike."""
    novelty = VisitNovelty(0.25, dims=2)
    points = [(np.nan, 0.3), (np.nan, 0.3, 9.0), (-np.inf, 0.3), (np.inf, 0.0), (0.1, 0.3)]
    total = sum(novelty.visit(np.asarray(p)) for p in points)
    assert sorted(novelty.counts.values()) == [1, 1, 1, 2]  # the two NaN points share a cell
    assert novelty.cells == {(None, 1): 3, (None, 0): 1, (0, 1): 1}
    assert total == pytest.approx(1 + 2 ** -0.5 + 1 + 1 + 1, rel=1e-12)


def test_points_shorter_than_dims_and_of_any_float_width_read_back_as_their_cells():
    """A 2-entry point with dims = 5 and the same point in float32 and float64: one cell, (1, -2)."""
    novelty = VisitNovelty(0.25, dims=5)
    for dtype in (np.float32, np.float64, np.float32):
        novelty.visit(np.array([0.3, -0.3], dtype=dtype))
    assert novelty.cells == {(1, -2): 3}
