"""Directions of the exploration environment's actions, checked against the camera's pose in
the world and against what the camera sees (docs/envs.md, "Actions")."""

import math

import numpy as np
import pytest

from generator.envs.actions import continuous_targets
from generator.envs.exploration import ExplorationEnv
from test_envs import room_scene

UP = np.array([0.0, 0.0, 1.0])
STEP, ANGLE = 1.0, 22.5


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    # camera at (0, -3, 1.5) looking along +Y, 10 degrees down, zero roll; a pole at (-0.8, 4)
    return room_scene(tmp_path_factory.mktemp("actions") / "room.blend")


def after(room, action, action_space="discrete"):
    """(start pose, pose after ``action``, start labels, labels after) from the room's camera."""
    env = ExplorationEnv(blend_files=[room], resolution=(48, 32), points_density=2.0, step=STEP, angle=ANGLE,
                         action_space=action_space)
    obs, _ = env.reset(seed=0)
    if action_space == "continuous":
        action = np.array(action, dtype=np.float32)
    obs2, _, _, _, info = env.step(action)
    assert not info["collided"]
    pole = env.sim.labels.index("Pole")
    env.close()
    return obs["pose"], obs2["pose"], obs["label"] == pole, obs2["label"] == pole


def forward(pose):
    return pose[:3, 2]  # OpenCV world_from_camera: the optical axis is the camera's +z


def horizontal_turn(f0, f1) -> float:
    """Signed angle (degrees) from f0 to f1 about world +Z (positive: counter-clockwise seen
    from above, a left turn)."""
    return math.degrees(math.atan2(np.cross(f0, f1) @ UP, f0[:2] @ f1[:2]))


def right_of(f):
    """The horizontal direction to the right of a camera looking along f, world Z up."""
    r = np.cross(f, UP)
    return r / np.linalg.norm(r)


def pole_column(mask) -> float:
    assert mask.sum() > 3
    return float(np.nonzero(mask)[1].mean())


def test_start_pose_is_the_room_camera(room):
    p0, _, _, _ = after(room, 0)
    assert np.allclose(p0[:3, 3], [0, -3, 1.5]) and np.allclose(forward(p0), [0, math.cos(0.1745329), -math.sin(0.1745329)])


@pytest.mark.parametrize("action, turn", [(3, ANGLE), (4, -ANGLE)])
def test_discrete_3_turns_left_and_4_right(room, action, turn):
    p0, p1, pole0, pole1 = after(room, action)
    f0, f1 = forward(p0), forward(p1)
    assert horizontal_turn(f0, f1) == pytest.approx(turn, abs=1e-9)
    assert np.cross(f0, f1) @ UP > 0 if action == 3 else np.cross(f0, f1) @ UP < 0
    assert np.array_equal(p1[:3, 3], p0[:3, 3]) and f1[2] == pytest.approx(f0[2], abs=1e-12)  # about world Z
    # what the camera sees: turning left moves the pole (6.5 deg left of centre) to the right of the image
    c0, c1 = pole_column(pole0), pole_column(pole1)
    assert c0 < 24 and (c1 > 24 if action == 3 else c1 < c0 - 8)


@pytest.mark.parametrize("action, along", [(0, "forward"), (1, "left"), (2, "right")])
def test_discrete_moves_go_forward_left_and_right(room, action, along):
    p0, p1, _, _ = after(room, action)
    d = p1[:3, 3] - p0[:3, 3]
    f0 = forward(p0)
    expected = {"forward": f0, "left": -right_of(f0), "right": right_of(f0)}[along]
    assert np.allclose(d, STEP * expected, atol=1e-12)
    assert np.array_equal(p1[:3, :3], p0[:3, :3])


def test_continuous_positive_yaw_turns_right_and_positive_pitch_looks_up(room):
    p0, p1, _, _ = after(room, [0, 0, 0, 1, 0], "continuous")
    f0, f1 = forward(p0), forward(p1)
    assert np.cross(f0, f1) @ UP < 0 and horizontal_turn(f0, f1) == pytest.approx(-ANGLE, abs=1e-9)
    assert f1[2] == pytest.approx(f0[2], abs=1e-12)  # pitch kept
    p0, p1, _, _ = after(room, [0, 0, 0, 0, 0.4], "continuous")
    f0, f1 = forward(p0), forward(p1)
    pitch0, pitch1 = (math.degrees(math.asin(f[2])) for f in (f0, f1))
    assert f1[2] > f0[2] and pitch0 == pytest.approx(-10.0, abs=1e-4) and pitch1 - pitch0 == pytest.approx(0.4 * ANGLE)
    assert horizontal_turn(f0, f1) == pytest.approx(0.0, abs=1e-9)
    assert np.allclose(p1[:3, 0], right_of(f1), atol=1e-12)  # zero roll: image x stays horizontal, to the right


@pytest.mark.parametrize("action, expected", [([1, 0, 0, 0, 0], "forward"), ([0, 0.5, 0, 0, 0], "right"),
                                              ([0, -1, 0, 0, 0], "left"), ([0, 0, 1, 0, 0], "up")])
def test_continuous_moves_go_forward_right_and_up(room, action, expected):
    p0, p1, _, _ = after(room, action, "continuous")
    d = p1[:3, 3] - p0[:3, 3]
    f0 = forward(p0)
    level = np.array([f0[0], f0[1], 0.0]) / np.linalg.norm(f0[:2])
    direction = {"forward": level, "right": 0.5 * right_of(f0), "left": -right_of(f0), "up": UP}[expected]
    assert np.allclose(d, STEP * direction, atol=1e-12)
    assert np.array_equal(p1[:3, :3], p0[:3, :3])


@pytest.mark.parametrize("down", [True, False])
def test_continuous_moves_head_where_the_image_top_points_when_looking_straight_down(down):
    # a camera looking straight down (up) whose image top points to world +Y (-Y): OpenCV
    # axes x right, y down the image, z forward
    z = np.array([0.0, 0.0, -1.0 if down else 1.0])
    y = np.array([0.0, -1.0, 0.0]) if down else np.array([0.0, 1.0, 0.0])
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    assert np.isclose(np.linalg.det(pose[:3, :3]), 1.0)
    _, moved = continuous_targets(pose, np.array([1.0, 0, 0, 0, 0]), 3.0, 22.5)
    # forward: toward the image's top looking down, its bottom looking up, i.e. +Y both times
    np.testing.assert_allclose(moved[:3, 3], [0.0, 3.0, 0.0], atol=1e-12)
    _, right = continuous_targets(pose, np.array([0, 1.0, 0, 0, 0]), 3.0, 22.5)
    # right: along the image's x axis, horizontal
    np.testing.assert_allclose(right[:3, 3], 3.0 * pose[:3, 0], atol=1e-12)
    # a yaw turn from there turns about world Z from that heading (no jump to +X)
    turned, _ = continuous_targets(pose, np.array([0, 0, 0, 1.0, 0]), 3.0, 22.5)
    heading = math.degrees(math.atan2(turned[1, 2], turned[0, 2]))
    assert math.isclose(heading, 90.0 - 22.5, abs_tol=1e-9)
