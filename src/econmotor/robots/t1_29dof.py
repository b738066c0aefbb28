"""Booster T1, 29 DoF: Holosoma's locomotion robot (facts copied from Holosoma 0.0.3 and holosoma_inference 0.1.3).

Sources (``tests/integration/test_robot_cards.py`` holds every value to them):

- holosoma ``config_values/robot.py`` ``t1_29dof_waist_wrist``: joints, effort limits, initial
  base position, torso, feet, PD gains by joint group, action scale and clip,
  ``asset.enable_self_collisions``, the MJCF ``t1/t1_29dof.xml``;
- holosoma ``config_values/loco/t1/experiment.py`` ``t1_29dof``: 200 Hz physics, decimation 4;
- holosoma_inference preset ``t1-29dof-loco``: default pose, ``loco_t1_29dof`` observation
  (T1's own scales: base_ang_vel 1.0, dof_vel 0.1), task ``locomotion``;
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
    7.0, 7.0,
    18.0, 18.0, 18.0, 18.0, 18.0, 18.0, 18.0,
    18.0, 18.0, 18.0, 18.0, 18.0, 18.0, 18.0,
    30.0,
    45.0, 30.0, 30.0, 60.0, 12.0, 12.0,
    45.0, 30.0, 30.0, 60.0, 12.0, 12.0,
)
#: W of winding heat per N m of a joint's effort limit, at that limit (:func:`scaled_heat_model`)
HEAT_AT_LIMIT_W_PER_NM = 4.3

CARD = RobotCard(
    **HOLOSOMA_LOCOMOTION,
    name="t1_29dof",
    mjcf_file="data/robots/t1/t1_29dof.xml",
    dof_names=(
        "AAHead_yaw", "Head_pitch",
        "Left_Shoulder_Pitch", "Left_Shoulder_Roll", "Left_Elbow_Pitch", "Left_Elbow_Yaw", "Left_Wrist_Pitch",
        "Left_Wrist_Yaw", "Left_Hand_Roll",
        "Right_Shoulder_Pitch", "Right_Shoulder_Roll", "Right_Elbow_Pitch", "Right_Elbow_Yaw", "Right_Wrist_Pitch",
        "Right_Wrist_Yaw", "Right_Hand_Roll",
        "Waist",
        "Left_Hip_Pitch", "Left_Hip_Roll", "Left_Hip_Yaw", "Left_Knee_Pitch", "Left_Ankle_Pitch", "Left_Ankle_Roll",
        "Right_Hip_Pitch", "Right_Hip_Roll", "Right_Hip_Yaw", "Right_Knee_Pitch", "Right_Ankle_Pitch",
        "Right_Ankle_Roll",
    ),
    default_dof_angles=(
        0.0, 0.0,  # head
        0.2, -1.35, 0.0, -0.5, 0.0, 0.0, 0.0,  # left arm
        0.2, 1.35, 0.0, 0.5, 0.0, 0.0, 0.0,  # right arm
        0.0,  # waist
        -0.2, 0.0, 0.0, 0.4, -0.25, 0.0,  # left leg
        -0.2, 0.0, 0.0, 0.4, -0.25, 0.0,  # right leg
    ),
    kp=(
        5.0, 5.0,
        20.0, 20.0, 20.0, 20.0, 20.0, 20.0, 20.0,
        20.0, 20.0, 20.0, 20.0, 20.0, 20.0, 20.0,
        200.0,
        200.0, 200.0, 200.0, 200.0, 50.0, 50.0,
        200.0, 200.0, 200.0, 200.0, 50.0, 50.0,
    ),
    kd=(
        0.5, 0.5,
        0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5,
        0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5,
        5.0,
        5.0, 5.0, 5.0, 5.0, 3.0, 3.0,
        5.0, 5.0, 5.0, 5.0, 3.0, 3.0,
    ),
    effort_limits=EFFORT_LIMITS,
    init_pos=(0.0, 0.0, 0.68),
    root_body="Trunk",
    torso_body="Trunk",
    foot_bodies=("left_foot_link", "right_foot_link"),
    foot_geoms=tuple(f"{side}_rail_{i}" for side in ("L", "R") for i in range(1, 8)),
    observation=locomotion_observation(29, scales={
        "actions": 1.0, "base_ang_vel": 1.0, "command_ang_vel": 1.0, "command_lin_vel": 1.0, "cos_phase": 1.0,
        "dof_pos": 1.0, "dof_vel": 0.1, "projected_gravity": 1.0, "sin_phase": 1.0}),
    holosoma_experiment="t1_29dof",
    inference_preset="t1-29dof-loco",
    sources={"robot": "holosoma 0.0.3 config_values/robot.py t1_29dof_waist_wrist",
             "simulator": "holosoma 0.0.3 config_values/loco/t1/experiment.py t1_29dof",
             "observation": "holosoma_inference 0.1.3 preset t1-29dof-loco",
             "fall rule": "assumption: econmotor's sim-to-sim evaluator and meter (risk 1 at fall_tilt_rad)"},
    # No datasheet of the T1's joint motors, nor its pack's capacity, is published: the constant is fitted
    # as the G1's, to the maker's walking figure on the task's assumed 504 Wh pack. The G1's constant (13.0)
    # does not carry over (it would put the T1 under 1 h), and the fit does not reproduce the maker's 4 h
    # standing (about 2.5 h standing under the shipped walker), so both are assumptions of this card.
    motor_model=scaled_heat_model(EFFORT_LIMITS, HEAT_AT_LIMIT_W_PER_NM, (
        "calibrated (assumption): k_j = 4.3 / effort limit W/(N m)^2, fitted so that Holosoma's shipped T1 PPO "
        "walker on the humanoid_locomotion_t1 course at its default 1 m/s command draws 504 Wh / 2 h = 252 W "
        "(the maker's about 2 h walking, on the task's assumed 504 Wh pack; benchmarks/motor_heat_calibration.py)")),
    stated_runtime=StatedRuntime(2.0, "walking", (
        "Booster Robotics, as its product announcements are reported: about 2 h walking, 4 h standing per "
        "charge (pack capacity not published)")),
)
