"""Unitree G1, 29 DoF: Holosoma's locomotion robot (facts copied from Holosoma 0.0.3 and holosoma_inference 0.1.3).

Sources (``tests/integration/test_robot_cards.py`` holds every value to them):

- holosoma ``config_values/robot.py`` ``g1_29dof``: joints, effort limits, initial base position,
  torso, feet, PD gains (``control.stiffness`` / ``damping`` by joint group, the rotor-inertia
  derived ``STIFFNESS_*`` / ``DAMPING_*`` constants), action scale and clip,
  ``asset.enable_self_collisions``, the MJCF ``g1/g1_29dof.xml``;
- holosoma ``config_values/loco/g1/experiment.py`` ``g1_29dof``: 200 Hz physics, decimation 4;
- holosoma_inference preset ``g1-29dof-loco``: default pose, ``loco_g1_29dof`` observation
  (terms, dims, scales, history), task ``locomotion`` (50 Hz, action scale 0.25, gait period 1 s);
- the shipped ONNX walkers' metadata: the same ``kp``, ``kd``, command ranges.
"""

from __future__ import annotations

from econmotor.robots.card import (
    HOLOSOMA_LOCOMOTION,
    RobotCard,
    StatedRuntime,
    locomotion_observation,
    scaled_heat_model,
)

EFFORT_LIMITS = (
    88.0, 139.0, 88.0, 139.0, 50.0, 50.0,
    88.0, 139.0, 88.0, 139.0, 50.0, 50.0,
    88.0, 50.0, 50.0,
    25.0, 25.0, 25.0, 25.0, 25.0, 5.0, 5.0,
    25.0, 25.0, 25.0, 25.0, 25.0, 5.0, 5.0,
)
#: W of winding heat per N m of a joint's effort limit, at that limit (:func:`scaled_heat_model`)
HEAT_AT_LIMIT_W_PER_NM = 13.0

CARD = RobotCard(
    **HOLOSOMA_LOCOMOTION,
    name="g1_29dof",
    mjcf_file="data/robots/g1/g1_29dof.xml",
    dof_names=(
        "left_hip_pitch_joint", "left_hip_roll_joint", "left_hip_yaw_joint", "left_knee_joint",
        "left_ankle_pitch_joint", "left_ankle_roll_joint",
        "right_hip_pitch_joint", "right_hip_roll_joint", "right_hip_yaw_joint", "right_knee_joint",
        "right_ankle_pitch_joint", "right_ankle_roll_joint",
        "waist_yaw_joint", "waist_roll_joint", "waist_pitch_joint",
        "left_shoulder_pitch_joint", "left_shoulder_roll_joint", "left_shoulder_yaw_joint", "left_elbow_joint",
        "left_wrist_roll_joint", "left_wrist_pitch_joint", "left_wrist_yaw_joint",
        "right_shoulder_pitch_joint", "right_shoulder_roll_joint", "right_shoulder_yaw_joint", "right_elbow_joint",
        "right_wrist_roll_joint", "right_wrist_pitch_joint", "right_wrist_yaw_joint",
    ),
    default_dof_angles=(
        -0.312, 0.0, 0.0, 0.669, -0.363, 0.0,  # left leg
        -0.312, 0.0, 0.0, 0.669, -0.363, 0.0,  # right leg
        0.0, 0.0, 0.0,  # waist
        0.2, 0.2, 0.0, 0.6, 0.0, 0.0, 0.0,  # left arm
        0.2, -0.2, 0.0, 0.6, 0.0, 0.0, 0.0,  # right arm
    ),
    kp=(
        40.179238471, 99.098427777, 40.179238471, 99.098427777, 28.501246196, 28.501246196,
        40.179238471, 99.098427777, 40.179238471, 99.098427777, 28.501246196, 28.501246196,
        40.179238471, 28.501246196, 28.501246196,
        14.250623098, 14.250623098, 14.250623098, 14.250623098, 14.250623098, 16.778327481, 16.778327481,
        14.250623098, 14.250623098, 14.250623098, 14.250623098, 14.250623098, 16.778327481, 16.778327481,
    ),
    kd=(
        2.557889765, 6.308801854, 2.557889765, 6.308801854, 1.814445687, 1.814445687,
        2.557889765, 6.308801854, 2.557889765, 6.308801854, 1.814445687, 1.814445687,
        2.557889765, 1.814445687, 1.814445687,
        0.907222843, 0.907222843, 0.907222843, 0.907222843, 0.907222843, 1.068141502, 1.068141502,
        0.907222843, 0.907222843, 0.907222843, 0.907222843, 0.907222843, 1.068141502, 1.068141502,
    ),
    effort_limits=EFFORT_LIMITS,
    init_pos=(0.0, 0.0, 0.8),
    root_body="pelvis",
    torso_body="torso_link",
    foot_bodies=("left_ankle_roll_link", "right_ankle_roll_link"),
    foot_geoms=tuple(f"{side}_foot{i}_collision" for side in ("left", "right") for i in range(1, 8)),
    observation=locomotion_observation(29, scales={
        "actions": 1.0, "base_ang_vel": 0.25, "command_ang_vel": 1.0, "command_lin_vel": 1.0, "cos_phase": 1.0,
        "dof_pos": 1.0, "dof_vel": 0.05, "projected_gravity": 1.0, "sin_phase": 1.0}),
    holosoma_experiment="g1_29dof",
    inference_preset="g1-29dof-loco",
    sources={"robot": "holosoma 0.0.3 config_values/robot.py g1_29dof",
             "simulator": "holosoma 0.0.3 config_values/loco/g1/experiment.py g1_29dof",
             "observation": "holosoma_inference 0.1.3 preset g1-29dof-loco",
             "fall rule": "assumption: econmotor's sim-to-sim evaluator and meter (risk 1 at fall_tilt_rad)"},
    # No datasheet of the G1's joint motors is published (torque constant, winding resistance, gear ratio):
    # the winding-heat constant is fitted to the maker's runtime (benchmarks/motor_heat_calibration.py).
    motor_model=scaled_heat_model(EFFORT_LIMITS, HEAT_AT_LIMIT_W_PER_NM, (
        "calibrated: k_j = 13.0 / effort limit W/(N m)^2 (13 W of winding heat per N m at a joint's limit, "
        "1.8 kW at the knee's 139 N m), fitted so that Holosoma's shipped G1 PPO walker on the "
        "humanoid_locomotion_g1 course at its default 1 m/s command (10 m legs, 20 s dwells) draws "
        "421.2 Wh / 2 h = 210.6 W: the maker's stated runtime (benchmarks/motor_heat_calibration.py, "
        "16 episodes, seeds 1000-1015)")),
    stated_runtime=StatedRuntime(2.0, "continuous operation", (
        "Unitree G1 spec sheet: about 2 h of battery life on the 9000 mAh, 421.2 Wh pack; Unitree's "
        "developer guide asks for straight knees and little standing still, where the battery goes")),
)
