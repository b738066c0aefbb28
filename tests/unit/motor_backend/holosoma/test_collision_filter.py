"""The sim-to-sim evaluator models collisions as Holosoma's MuJoCo simulator does (sim2sim.apply_collision_filter).

A two-legged body whose feet overlap each other and rest on the floor: with self-collisions off the feet touch
the floor only; with them on, each other too; a geom the MJCF excludes from collisions stays excluded.
"""

from __future__ import annotations

import mujoco
import pytest

from econmotor.motor_backend.holosoma.sim2sim import apply_collision_filter

MJCF = """
<mujoco>
  <worldbody>
    <body name="pelvis" pos="0 0 0.5">
      <freejoint/>
      <geom name="pelvis_visual" type="sphere" size="0.05" contype="0" conaffinity="0"/>
      <body name="left_leg">
        <joint type="hinge" axis="0 1 0"/>
        <geom name="left_foot" type="capsule" fromto="0 0.02 0 0 0.02 -0.49" size="0.03"/>
      </body>
      <body name="right_leg">
        <joint type="hinge" axis="0 1 0"/>
        <geom name="right_foot" type="capsule" fromto="0 -0.02 0 0 -0.02 -0.49" size="0.03"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def _contacts(self_collisions: bool) -> tuple[set[tuple[str, str]], int]:
    spec = mujoco.MjSpec.from_string(MJCF)
    spec.worldbody.add_geom(name="floor", type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 0.05])
    changed = apply_collision_filter(spec, self_collisions)
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    pairs = {tuple(sorted((model.geom(int(c.geom1)).name, model.geom(int(c.geom2)).name)))
             for c in data.contact[:data.ncon]}
    return pairs, changed


@pytest.mark.parametrize("self_collisions", [False, True])
def test_robot_touches_the_floor_and_itself_only_with_self_collisions(self_collisions: bool) -> None:
    pairs, changed = _contacts(self_collisions)
    assert changed == 2  # the two feet; the visual geom keeps contype = conaffinity = 0
    assert {("floor", "left_foot"), ("floor", "right_foot")} <= pairs
    assert (("left_foot", "right_foot") in pairs) is self_collisions
    assert not any("pelvis_visual" in pair for pair in pairs)
