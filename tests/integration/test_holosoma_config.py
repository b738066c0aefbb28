"""The Holosoma backend's main-interpreter side: planning, datapack mapping, formulas, recordings.

Fast: no Holosoma process is started. Real YAML files, real npz files.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from econmotor.config.datapacks import (
    DatapackProvider,
    load_datapack_configs,
    parse_datapack,
)
from econmotor.couriers import policy_import
from econmotor.couriers.datapack_mapping import map_datapacks, validate_motion_npz
from econmotor.economics import courier_formulas as cf
from econmotor.errors import BackendError, ConfigError
from econmotor.locomotion.task import meter_constants, meter_settings, task_settings
from econmotor.motor_backend.holosoma.econ_formulas import (
    base_tilt_rad,
    commanded_progress_m_per_s,
    overlay_term_rates,
)
from econmotor.motor_backend.holosoma.host import backend as holosoma_backend
from econmotor.motor_backend.holosoma.host.jobs import holosoma_error_text
from econmotor.motor_backend.holosoma.host.plan import Capabilities, choose_simulator, plan_training
from econmotor.motor_backend.holosoma.host.recording_metrics import episodes_from_recording
from econmotor.motor_backend.holosoma.protocol import PREFIX, parse_line
from econmotor.robots import card
from econmotor.tasks import get_task

REPO = Path(__file__).resolve().parents[2]
DATAPACK = REPO / "configs" / "datapacks" / "example_holosoma_datapack.yaml"
CPU = Capabilities(mujoco_warp=True)
GPU = Capabilities(cuda=True, isaacgym=True, mujoco_warp=True)


def test_backend_module_imports_without_holosoma_or_torch() -> None:
    code = ("import sys, econmotor.motor_backend.holosoma.host.backend as b; "
            "print(sorted(m for m in ('torch', 'holosoma') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_classic_mujoco_runs_one_env_and_caps_cpu_steps() -> None:
    sim, device = choose_simulator("auto", CPU)
    assert (sim, device) == ("mujoco", "cpu")
    plan = plan_training(experiment="g1_29dof", algo="ppo", simulator=sim, device=device, num_envs=2048,
                         max_steps=50_000, cpu_max_env_steps=9_600)
    assert plan.num_envs == 1 and plan.iterations == 400 and plan.env_steps == 9_600
    assert any("2048 -> 1" in m for m in plan.messages) and any("50000 -> 9600" in m for m in plan.messages)


def test_gpu_request_runs_unchanged() -> None:
    sim, device = choose_simulator("auto", GPU)
    assert (sim, device) == ("isaacgym", "cuda:0")
    plan = plan_training(experiment="g1_29dof", algo="ppo", simulator=sim, device=device, num_envs=2048,
                         max_steps=50_000, cpu_max_env_steps=9_600)
    assert plan.num_envs == 2048 and plan.iterations == math.ceil(50_000 / (2048 * 24)) and not plan.messages
    assert choose_simulator("auto", Capabilities(cuda=True, mujoco_warp=True)) == ("mjwarp", "cuda:0")
    with pytest.raises(ConfigError, match="isaacgym needs a CUDA GPU"):
        choose_simulator("isaacgym", CPU)


def test_num_envs_zero_is_the_simulators_default_not_an_error() -> None:
    """`econmotor report --motor-backend holosoma` without --num-envs sends 0: it must run."""
    for sim, device, envs in (("mujoco", "cpu", 1), ("mjwarp", "cpu", 64), ("isaacgym", "cuda:0", 4096)):
        plan = plan_training(experiment="g1_29dof", algo="ppo", simulator=sim, device=device, num_envs=0,
                             max_steps=50_000, cpu_max_env_steps=9_600)
        assert plan.num_envs == envs and not any("num_envs" in m for m in plan.messages)
    with pytest.raises(ConfigError, match="num_envs must be >= 0"):
        plan_training(experiment="g1_29dof", algo="ppo", simulator="mujoco", device="cpu", num_envs=-1,
                      max_steps=10, cpu_max_env_steps=9_600)


def test_fast_sac_on_cpu_counts_global_steps() -> None:
    plan = plan_training(experiment="g1_29dof_fast_sac", algo="fast_sac", simulator="mjwarp", device="cpu",
                         num_envs=2048, max_steps=50_000, cpu_max_env_steps=6_400)
    assert plan.num_envs == 64 and plan.iterations == 100 and plan.cpu_sized


def test_example_datapack_maps_onto_holosoma_randomization_and_curriculum() -> None:
    packs = load_datapack_configs([DATAPACK])
    bundle = DatapackProvider().resolve("humanoid_locomotion_g1", [], packs)
    over = map_datapacks(bundle, packs, uses_motion_clip=False)
    assert over.terrain == "terrain_locomotion_plane"
    assert over.randomization == {"randomize_friction_startup": {"friction_range": [0.5, 1.0], "enabled": True}}
    assert over.curriculum == {"initial_scale": 0.1, "max_scale": 1.0}
    assert over.motion_file is None and "ignored" in over.messages[0]


def test_unknown_datapack_key_names_the_datapack_and_supported_keys(tmp_path: Path) -> None:
    path = tmp_path / "pack.yaml"
    path.write_text("id: p\ndomain_randomization:\n  friction: [0.5, 1.0]\n", encoding="utf-8")
    packs = load_datapack_configs([path])
    bundle = DatapackProvider().resolve("humanoid_locomotion_g1", [], packs)
    with pytest.raises(ConfigError) as info:
        map_datapacks(bundle, packs, uses_motion_clip=False)
    text = str(info.value)
    assert str(path) in text and "domain_randomization.friction" in text and "friction_range" in text


def test_highest_weight_clip_becomes_the_validated_motion_file(tmp_path: Path) -> None:
    clip = REPO / "data" / "mocap" / "logging_clip_01.npz"
    info = validate_motion_npz(clip, "x")
    assert info["joints"] == 29 and info["duration_s"] == pytest.approx(3.0)
    broken = tmp_path / "broken.npz"
    with np.load(clip) as data:
        np.savez(broken, **{k: data[k] for k in data.files if k != "body_quat_w"})
    pack = parse_datapack({"id": "wbt", "motion_clips": [{"path": str(clip), "weight": 2.0},
                                                          {"path": str(broken), "weight": 1.0}]}, "wbt.yaml")
    bundle = DatapackProvider().resolve("humanoid_wbt_g1", [], [pack])
    over = map_datapacks(bundle, [pack], uses_motion_clip=True)
    assert over.motion_file == str(clip.resolve()) and over.motion_duration_s == pytest.approx(3.0)
    bad = parse_datapack({"id": "bad", "motion_clips": [{"path": str(broken), "weight": 1.0}]}, "bad.yaml")
    with pytest.raises(ConfigError, match=r"bad.yaml.*body_quat_w"):
        map_datapacks(DatapackProvider().resolve("humanoid_wbt_g1", [], [bad]), [bad], uses_motion_clip=True)


def test_econ_formulas_by_hand() -> None:
    tau, qd = np.array([[10.0, -5.0]]), np.array([[2.0, 4.0]])
    assert cf.mechanical_power_w(tau, qd, np)[0] == pytest.approx(20 + 20)
    v, c = np.array([[1.0, 1.0], [0.5, 0.0]]), np.array([[1.0, 0.0], [0.05, 0.0]])
    assert commanded_progress_m_per_s(v, c).tolist() == pytest.approx([1.0, 0.0])  # standing command: none
    tilt = 0.4  # rad about x: q = (sin(t/2), 0, 0, cos(t/2))
    q = np.array([math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)])
    assert base_tilt_rad(q, np) == pytest.approx(tilt)
    steps, dt, episode_s = 1000, 0.02, 20.0  # 1 m/s for 20 s with 10 m units: 2 units in 20 s = 360/h
    meter = {"leg_distance_m": 10.0, "drivetrain_efficiency": 0.8, "idle_power_w": 50.0, "tilt_margin_rad": 0.2,
             "fall_tilt_rad": 0.8}
    rates = overlay_term_rates(progress_units_per_s=np.full(steps, 0.1), mechanical_w=np.full(steps, 288.0),
                               fell=np.zeros(steps), tilt_rad=np.full(steps, 0.5), novelty=np.zeros(steps),
                               constants=meter_constants(meter, dt), episode_s=episode_s, xp=np)
    assert np.sum(rates["mpl_per_hour"] * dt) == pytest.approx(360.0)
    assert np.sum(rates["energy_kwh"] * dt) == pytest.approx((288.0 / 0.8 + 50.0) * 20 / 3.6e6)  # idle counted
    assert np.sum(rates["risk_score"] * dt) == pytest.approx((0.5 - 0.2) / (0.8 - 0.2))  # beyond the margin


def test_meter_settings_come_from_the_catalog_entry_and_name_a_missing_key() -> None:
    spec = get_task("humanoid_locomotion_g1")
    entry = dict(spec.locomotion)
    meter = meter_settings(spec.task_id, entry, spec.source)
    assert meter == {"leg_distance_m": entry["unit_length_m"], "drivetrain_efficiency": entry["drivetrain_efficiency"],
                     "idle_power_w": entry["idle_power_w"], "tilt_margin_rad": entry["tilt_margin_rad"],
                     "fall_tilt_rad": card(entry["robot"]).fall_tilt_rad}  # the fall rule is the robot card's
    without_idle = {k: v for k, v in entry.items() if k != "idle_power_w"}
    with pytest.raises(ConfigError, match=r"holosoma.yaml.*g1\.locomotion\.idle_power_w.*courier meter"):
        meter_settings(spec.task_id, without_idle, spec.source)
    with pytest.raises(ConfigError, match=r"tilt_margin_rad.*fall tilt of robot card g1_29dof"):
        meter_settings(spec.task_id, {**entry, "tilt_margin_rad": 0.9}, spec.source)
    with pytest.raises(ConfigError, match=r"unknown robot 'g9'.*g1_29dof"):
        meter_settings(spec.task_id, {**entry, "robot": "g9"}, spec.source)


def _recording(path: Path, steps: int, fall_at: int, joints: int = 29) -> None:
    reset = np.zeros(steps, bool)
    reset[fall_at] = True
    arrays = {
        "dof_pos": np.zeros((steps, joints)), "torques_substep": np.full((steps, 4, joints), 10.0),
        "dof_vel_substep": np.full((steps, 4, joints), 1.0),
        "root_quat_xyzw": np.tile([0.0, 0.0, 0.0, 1.0], (steps, 1)),
        "reset": reset, "time_out": np.zeros(steps, bool), "reward": np.ones(steps),
        "base_lin_vel": np.tile([0.5, 0.0, 0.0], (steps, 1)),
        "commanded_velocity": np.tile([0.5, 0.0, 0.0], (steps, 1)),
        "_metadata_json": np.array(json.dumps({"dt": 0.02})),
    }
    np.savez(path, **arrays)


def test_recording_is_split_into_episodes_with_econ_raw_metrics(tmp_path: Path) -> None:
    path = tmp_path / "rec.npz"
    _recording(path, steps=100, fall_at=29)
    spec = get_task("humanoid_locomotion_g1")
    settings = task_settings(spec) | {"unit_duration_s": 10.0, "novelty_rate": 0.01}
    meter = meter_settings(spec.task_id, settings, spec.source)
    episodes = episodes_from_recording(path, settings, meter, num_episodes=5)
    assert [e["length_steps"] for e in episodes] == [30, 70]
    first = episodes[0]
    assert first["termination_reason"] == "fall" and first["errors"] == 1
    assert first["units_completed"] == pytest.approx(0.5 * 30 * 0.02 / 10.0)
    # 29 joints at 10 N m and 1 rad/s: 290 W mechanical, and the G1 card's winding heat sum_j k_j 10^2
    heat_w = 100.0 * float(card(settings["robot"]).heat_coeff().sum())
    assert heat_w > 100.0
    assert first["energy_wh"] == pytest.approx((290.0 / 0.8 + heat_w + meter["idle_power_w"]) * 30 * 0.02 / 3600)
    assert first["risk_score"] == 0 and first["return"] == 30


def test_protocol_lines_and_holosoma_error_text() -> None:
    assert parse_line("╰────╯" + PREFIX + '{"event": "progress", "done": 1}') == {"event": "progress", "done": 1}
    assert parse_line("INFO training") is None
    log = ["INFO start\n", "Traceback (most recent call last):\n", '  File "x.py"\n', "ValueError: bad motion\n"]
    assert holosoma_error_text(log).splitlines() == ["Traceback (most recent call last):", '  File "x.py"',
                                                     "ValueError: bad motion"]


def test_missing_holosoma_environment_says_how_to_build_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(holosoma_backend.VENV_ENV, raising=False)
    monkeypatch.setattr(policy_import, "_REPO_ROOT", tmp_path)
    with pytest.raises(BackendError, match="make holosoma"):
        holosoma_backend.find_holosoma_python(tmp_path / "nowhere")
