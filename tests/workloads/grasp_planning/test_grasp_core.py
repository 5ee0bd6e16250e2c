"""The pure core, against numbers worked out by hand: shapes, arg-max, pose maths, analytic quality."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from workloads.grasp_planning.camera import Intrinsics, approach_quaternion, grasp_pose, to_original_pixel
from workloads.grasp_planning.decode import decode_best, tip_depth
from workloads.grasp_planning.network import GraspNet, fill_holes
from workloads.grasp_planning.quality import Gripper, grasp_quality, nominal_quality
from workloads.grasp_planning.scene import Primitive, Scene, render

TABLE = 0.7
INTR = Intrinsics(fx=280.0, fy=280.0, cx=63.5, cy=63.5)  # 2.5 mm per pixel on the table
G = Gripper()


@pytest.mark.parametrize("shape", [(2, 1, 96, 128), (1, 1, 61, 77)])
def test_network_maps_every_pixel_for_every_angle(shape: tuple[int, int, int, int]) -> None:
    net = GraspNet(k=8, channels=16).eval()
    with torch.no_grad():
        quality, width = net(torch.zeros(shape))
    assert quality.shape == (shape[0], 8, *shape[2:])
    assert width.shape == quality.shape


def test_decode_picks_the_best_cell_and_its_angle() -> None:
    q = np.zeros((4, 3, 5), dtype=np.float32)
    w = np.zeros_like(q)
    q[1, 2, 4], w[1, 2, 4] = 0.9, 0.03
    q[3, 0, 1] = 0.8
    pick = decode_best(q, w)
    assert (pick.angle_index, pick.u, pick.v) == (1, 4, 2)
    assert pick.angle == pytest.approx(math.pi / 4)
    assert (pick.quality, pick.width) == (pytest.approx(0.9), pytest.approx(0.03))
    mask = np.ones((3, 5), dtype=bool)
    mask[2, 4] = False
    second = decode_best(q, w, mask=mask)
    assert (second.angle_index, second.u, second.v) == (3, 1, 0)


def test_decode_breaks_ties_in_angle_row_column_order() -> None:
    q = np.ones((2, 2, 2))
    assert (decode_best(q, q).angle_index, decode_best(q, q).v, decode_best(q, q).u) == (0, 0, 0)
    with pytest.raises(ValueError, match=r"quality and width must both be \(k, H, W\), got \(2, 2, 2\) and \(2, 2\)"):
        decode_best(q, q[0])


def test_pose_deprojects_the_pixel_and_turns_about_the_optical_axis() -> None:
    intr = Intrinsics(fx=500.0, fy=400.0, cx=320.0, cy=240.0)
    pose = grasp_pose(intr, u=420.0, v=140.0, depth=0.8, angle=math.pi / 2)
    # x = (420 - 320) * 0.8 / 500, y = (140 - 240) * 0.8 / 400
    assert pose.position == pytest.approx((0.16, -0.2, 0.8))
    assert pose.orientation == pytest.approx((0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)))


@pytest.mark.parametrize("angle", [0.0, 0.3, math.pi / 2, 2.5])
def test_quaternion_turns_the_gripper_x_axis_onto_the_closing_direction(angle: float) -> None:
    x, y, z, w = approach_quaternion(angle)
    # first column of the rotation matrix of a unit quaternion
    col = (1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w))
    assert col == pytest.approx((math.cos(angle), math.sin(angle), 0.0))
    assert x * x + y * y + z * z + w * w == pytest.approx(1.0)


def test_resized_intrinsics_and_pixels_round_trip() -> None:
    intr = Intrinsics(fx=540.0, fy=540.0, cx=319.5, cy=239.5).scaled(2.0)
    assert (intr.fx, intr.cx, intr.cy) == (270.0, 159.5, 119.5)
    assert to_original_pixel(159.5, 119.5, 2.0) == (319.5, 239.5)
    # the same 3-D point projects to matching pixels before and after the resize
    u, v = intr.project(0.1, -0.05, 0.7)
    assert to_original_pixel(u, v, 2.0) == pytest.approx(Intrinsics(540.0, 540.0, 319.5, 239.5).project(0.1, -0.05, 0.7))


def _scene(*objects: Primitive) -> tuple[Scene, object]:
    scene = Scene(table_z=TABLE, objects=objects)
    return scene, render(scene, INTR, height=128, width=128)


BOX = Primitive("box", (0.0, 0.0, TABLE - 0.03), 0.0, (0.02, 0.05, 0.03))


def _nominal(scene: Scene, truth: object, *, x: float, y: float, angle: float) -> tuple[float, float]:
    u, v = INTR.project(x, y, TABLE)
    ui, vi = int(round(u)), int(round(v))
    q, w = nominal_quality(
        scene, truth, INTR, G, x=np.array([x]), y=np.array([y]), zs=np.array([float(truth.depth[vi, ui])]),
        obj=np.array([truth.ids[vi, ui]]), angle=np.array([angle]),
    )
    return float(q[0]), float(w[0])


def test_render_sees_the_box_top_and_the_table() -> None:
    _, truth = _scene(BOX)
    assert truth.depth[64, 64] == pytest.approx(0.64)
    assert truth.ids[64, 64] == 0
    assert truth.depth[64, 5] == pytest.approx(TABLE) and truth.ids[64, 5] == -1


def test_box_quality_by_hand() -> None:
    scene, truth = _scene(BOX)
    # face-on across the 40 mm side: inside both friction cones, 20 mm deep, fingers clear
    assert _nominal(scene, truth, x=0.0, y=0.0, angle=0.0) == pytest.approx((1.0, 0.04))
    # along the 100 mm side: wider than the 85 mm opening
    assert _nominal(scene, truth, x=0.0, y=0.0, angle=math.pi / 2) == (0.0, 0.0)
    # 20 degrees off the face normal, friction 0.5: (cos 20 - cos atan .5) / (1 - cos atan .5)
    cos_max = 1 / math.sqrt(1.25)
    q, w = _nominal(scene, truth, x=0.0, y=0.0, angle=math.radians(20))
    assert q == pytest.approx((math.cos(math.radians(20)) - cos_max) / (1 - cos_max))
    assert w == pytest.approx(0.04 / math.cos(math.radians(20)))
    # 30 degrees is outside the 26.6 degree friction cone
    assert _nominal(scene, truth, x=0.0, y=0.0, angle=math.radians(30))[0] == 0.0
    # robust: every centre within 5 mm is still face-on
    assert grasp_quality(scene, truth, INTR, G, u=63.5, v=63.5, angle=0.0) == pytest.approx(1.0)


def test_cylinder_chord_quality_by_hand() -> None:
    cyl = Primitive("cylinder", (0.0, 0.0, TABLE - 0.04), 0.0, (0.03, 0.04, 0.0))
    scene, truth = _scene(cyl)
    # a chord 10 mm off the axis meets the surface at asin(1/3) from the normal
    q, w = _nominal(scene, truth, x=0.0, y=0.01, angle=0.0)
    cos_max = 1 / math.sqrt(1.25)
    assert q == pytest.approx((math.sqrt(8) / 3 - cos_max) / (1 - cos_max))
    assert w == pytest.approx(2 * math.sqrt(0.03**2 - 0.01**2))
    assert _nominal(scene, truth, x=0.0, y=0.015, angle=0.0)[0] == 0.0  # 30 degrees off


def test_a_neighbour_in_the_fingers_path_blocks_the_grasp() -> None:
    wall = Primitive("box", (0.04, 0.0, TABLE - 0.05), 0.0, (0.005, 0.03, 0.05))
    scene, truth = _scene(BOX, wall)
    assert _nominal(scene, truth, x=0.0, y=0.0, angle=0.0)[0] == 0.0
    low = Primitive("box", (0.04, 0.0, TABLE - 0.002), 0.0, (0.005, 0.03, 0.002))  # below the finger tips
    scene, truth = _scene(BOX, low)
    assert _nominal(scene, truth, x=0.0, y=0.0, angle=0.0)[0] == pytest.approx(1.0)


def test_bin_walls_are_not_grasped() -> None:
    wall = Primitive("box", (0.0, 0.0, TABLE - 0.03), 0.0, (0.005, 0.05, 0.03), graspable=False)
    scene, truth = _scene(wall)
    assert _nominal(scene, truth, x=0.0, y=0.0, angle=0.0) == (0.0, 0.0)


def test_tip_depth_stays_above_the_floor() -> None:
    depth = np.full((40, 40), 0.70, dtype=np.float32)
    depth[15:25, 15:25] = 0.69  # a 10 mm tall object: 20 mm down would hit the table
    z = tip_depth(depth, u=20, v=20, pixel_size=0.0025, grasp_depth=0.02, open_width=0.085, clearance=0.004)
    assert z == pytest.approx(0.696)
    depth[15:25, 15:25] = 0.60
    z = tip_depth(depth, u=20, v=20, pixel_size=0.0025, grasp_depth=0.02, open_width=0.085, clearance=0.004)
    assert z == pytest.approx(0.62)


def test_holes_take_the_farthest_neighbour() -> None:
    d = torch.tensor([[[[0.5, 0.5, 0.7], [0.5, 0.0, 0.7], [0.5, 0.5, 0.7]]]])
    filled = fill_holes(d)
    assert float(filled[0, 0, 1, 1]) == pytest.approx(0.7)
    assert bool((filled > 0).all())
