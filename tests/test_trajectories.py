"""Camera path planners: collision-free, deterministic, the paper's five actions."""

import math

import numpy as np
import pytest

from generator.geometry.camera import look_at, validate_rigid
from generator.geometry.collision import position_is_free, segment_is_free
from generator.geometry.raycast import SceneGeometry
from generator.scene.meshes import MeshBuilder
from generator.geometry.parts import MeshPart, closed_and_orientation
from trajectories import (ACTIONS, Trajectory, TrajectoryError, lawnmower, modified_random_walk, orbit,
                          random_walk, spline_flythrough)

RADIUS = 0.5


def _part(name, builder):
    d = builder.build()
    tris = np.concatenate([d.quads[:, [0, 1, 2]], d.quads[:, [0, 2, 3]], d.tris])
    closed, outward = closed_and_orientation(d.vertices, tris)
    return MeshPart(name, name, d.vertices, tris, closed=closed, outward=outward)


class Checker:
    """The MotionChecker interface on a numpy scene (what the Simulator does with bpy)."""

    def __init__(self):
        parts = [_part("Ground", MeshBuilder().box((120, 120, 0.5), (0, 0, -0.25)))]
        for k, (x, y, h) in enumerate([(0, 0, 15), (20, 10, 25), (-20, 15, 10), (15, -20, 8), (-15, -15, 12)]):
            parts.append(_part(f"Block{k}", MeshBuilder().box((10, 10, h), (x, y, h / 2))))
        parts.append(_part("Wall", MeshBuilder().box((30, 0.3, 4), (0, -30, 2))))
        self.geometry = SceneGeometry(parts)
        self.moves = 0

    def can_move(self, a, b):
        self.moves += 1
        return segment_is_free(self.geometry, np.asarray(a, float), np.asarray(b, float), RADIUS)

    def is_free(self, p):
        return position_is_free(self.geometry, np.asarray(p, float), RADIUS)


@pytest.fixture(scope="module")
def checker():
    return Checker()


def _assert_swept_free(geometry, positions):
    """Independent check: sample the path every 2 cm; the sphere never touches a surface."""
    pts = [positions[:1]]
    for a, b in zip(positions[:-1], positions[1:]):
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / 0.02)) + 1)
        pts.append(a + np.linspace(0, 1, n)[1:, None] * (b - a))
    pts = np.concatenate(pts)
    d = geometry.distance(pts)
    assert d.min() >= RADIUS - 2e-3, f"the camera sphere comes {d.min():.3f} m from a surface"
    assert not geometry.inside_solid(pts).any()


def _start():
    return look_at((5.0, -40.0, 2.0), (5.0, 0.0, 2.0))


def _plans(checker, seed):
    rng = lambda: np.random.default_rng(seed)  # noqa: E731
    return {
        "random_walk": random_walk(checker, _start(), 150, rng(), step=1.5, angle=20),
        "modified_random_walk": modified_random_walk(checker, _start(), 150, rng(), step=1.5, angle=20),
        "orbit": orbit(checker, (0, 0), 35.0, 8.0, 60, look_at_height=5.0),
        "lawnmower": lawnmower(checker, ((-40, -40), (40, 40)), 12.0, 80, spacing=20.0),
        "spline": spline_flythrough(checker, ((-45, -45, 2), (45, 45, 20)), 60, rng(), speed=4.0),
    }


def test_every_kind_is_collision_free_and_deterministic(checker):
    a, b, c = _plans(checker, 3), _plans(checker, 3), _plans(checker, 4)
    for kind, traj in a.items():
        assert traj.kind == kind and len(traj) >= 60
        for pose in traj.poses:
            validate_rigid(pose)
        _assert_swept_free(checker.geometry, traj.positions)
        np.testing.assert_array_equal(traj.poses, b[kind].poses)
        np.testing.assert_allclose(np.diff(traj.timestamps), 0.1)
        if kind in ("random_walk", "modified_random_walk", "spline"):
            assert not np.array_equal(traj.poses, c[kind].poses)
    # the y = 0 pass crosses the 15 m block: asked for 12 m, the survey rises in 5 m steps to 17 m
    assert a["lawnmower"].params["altitude_m"] == 17.0
    assert a["orbit"].params["altitude_m"] == 8.0  # the 35 m circle is clear at 8 m


def test_random_walks_use_exactly_the_five_actions(checker):
    for planner in (random_walk,):  # the modified walk's steps: tests/test_baselines.py
        traj = planner(checker, _start(), 200, np.random.default_rng(1), step=1.0, angle=15)
        assert len(traj.actions) == 200 and set(traj.actions) <= set(ACTIONS)
        for k, action in enumerate(traj.actions):
            before, after = traj.poses[k], traj.poses[k + 1]
            move = after[:3, 3] - before[:3, 3]
            if action.startswith("turn"):
                assert np.allclose(move, 0)
                yaw = math.degrees(math.atan2(after[1, 2], after[0, 2]) - math.atan2(before[1, 2], before[0, 2]))
                assert (yaw + 180) % 360 - 180 == pytest.approx(15 if action == "turn_left" else -15, abs=1e-6)
            elif np.allclose(move, 0):
                continue  # refused move: the pose stays
            else:
                axis = {"forward": before[:3, 2], "left": -before[:3, 0], "right": before[:3, 0]}[action]
                np.testing.assert_allclose(move, axis, atol=1e-9)
    rw = random_walk(checker, _start(), 300, np.random.default_rng(2))
    counts = {a: rw.actions.count(a) for a in ACTIONS}
    assert min(counts.values()) > 30  # uniform over the five


def test_modified_walk_goes_straight_until_blocked(checker):
    traj = modified_random_walk(checker, _start(), 80, np.random.default_rng(5), step=1.0, angle=15)
    first_turn = next(k for k, a in enumerate(traj.actions) if a != "forward")
    pose = traj.poses[first_turn]
    ahead = pose[:3, 3] + pose[:3, 2]
    assert not checker.can_move(pose[:3, 3], ahead)  # it turned only when forward was blocked
    assert first_turn >= 5


def test_save_load_round_trip(checker, tmp_path):
    traj = random_walk(checker, _start(), 20, np.random.default_rng(0))
    back = Trajectory.load(traj.save(tmp_path / "walk.npz"))
    np.testing.assert_array_equal(back.poses, traj.poses)
    np.testing.assert_array_equal(back.timestamps, traj.timestamps)
    assert back.actions == traj.actions and back.kind == traj.kind and back.params == traj.params
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(TrajectoryError, match="not a trajectory"):
        Trajectory.load(tmp_path / "junk.npz")
    with pytest.raises(TrajectoryError, match="not found"):
        Trajectory.load(tmp_path / "missing.npz")
    # other arrays: a one-line TrajectoryError saying what a trajectory file holds
    np.save(tmp_path / "poses.npy", traj.poses)
    np.savez(tmp_path / "mine.npz", poses=traj.poses, timestamps=traj.timestamps)
    np.savez(tmp_path / "list.npz", poses=traj.poses, timestamps=traj.timestamps, actions=np.array(traj.actions),
             header=np.array("[1, 2]"))
    for name, words in (("poses.npy", "holds one array"), ("mine.npz", "has no actions, header"),
                        ("list.npz", "not a JSON object")):
        with pytest.raises(TrajectoryError, match=words):
            Trajectory.load(tmp_path / name)


@pytest.mark.parametrize("kwargs", [{"steps": 0}, {"step": -1.0}, {"angle": 0.0}])
def test_bad_walk_parameters(checker, kwargs):
    args = {"steps": 10, "step": 1.0, "angle": 15.0} | kwargs
    with pytest.raises(ValueError):
        random_walk(checker, _start(), args["steps"], np.random.default_rng(0), step=args["step"], angle=args["angle"])


def test_walk_matches_the_simulators_own_moves(tmp_path):
    """The planner's actions mean what the Simulator's move/turn calls do."""
    import scenes
    from generator import Simulator

    sim = Simulator(scenes.walls_scene(tmp_path / "walls.blend"), points_density=1, collision_radius=0.3)
    start = sim.get_world_from_camera()
    traj = random_walk(sim, start, 60, np.random.default_rng(9), step=0.8, angle=30)
    calls = {"forward": lambda: sim.move_camera_forward(0.8), "left": lambda: sim.move_camera_right(-0.8),
             "right": lambda: sim.move_camera_right(0.8), "turn_left": lambda: sim.turn_camera_right(-30),
             "turn_right": lambda: sim.turn_camera_right(30)}
    for k, action in enumerate(traj.actions):
        calls[action]()
        np.testing.assert_allclose(sim.get_world_from_camera(), traj.poses[k + 1], atol=1e-9)


def test_bounded_walks_stay_in_their_box(checker):
    from trajectories import BoundedChecker

    lo, hi = np.array([-10.0, -45.0, 1.0]), np.array([30.0, -25.0, 3.0])
    bounded = BoundedChecker(checker, lo, hi)
    for walk in (random_walk, modified_random_walk):
        traj = walk(bounded, _start(), 300, np.random.default_rng(3), step=1.5, angle=20)
        p = traj.positions
        assert np.all(p >= lo) and np.all(p <= hi)
        assert np.ptp(p[:, 0]) > 5  # it does move around inside
        _assert_swept_free(checker.geometry, p)
    # unbounded, the same modified walk leaves that box (the wall is not a wall for it)
    free = modified_random_walk(checker, _start(), 300, np.random.default_rng(3), step=1.5, angle=20)
    assert not np.all((free.positions >= lo) & (free.positions <= hi))
    with pytest.raises(ValueError, match="lo <= hi"):
        BoundedChecker(checker, hi, lo)


def test_a_fly_through_too_long_for_its_box_is_refused_at_once(checker):
    """10,000 frames at 3 m/s (3 km) need waypoints 250 m apart in a 129 m box: a one-line error
    (the waypoint draw used to loop forever)."""
    with pytest.raises(TrajectoryError, match="3000 m .* more than the 129 m diagonal of its box: use fewer frames"):
        spline_flythrough(checker, ((-45, -45, 2), (45, 45, 20)), 10_000, np.random.default_rng(0))


class _Free:
    """A MotionChecker with no obstacles: every move is allowed."""

    def can_move(self, a, b):
        return True

    def is_free(self, p):
        return True


_RNG = np.random.default_rng


@pytest.mark.parametrize("call,message", [
    (lambda c: orbit(c, (0, 0), 10, 10, 8, fps=0), "fps must be a finite number > 0, got 0"),
    (lambda c: orbit(c, (0, 0), 10, 10, 8, turns=0), "turns must be a nonzero number with |turns| <= frames / 2 = 4"),
    (lambda c: orbit(c, (0, 0), 10, 10, 8, turns=5), "turns must be a nonzero number"),
    (lambda c: orbit(c, (0, 0), float("nan"), 10, 8), "radius must be a finite number > 0, got nan"),
    (lambda c: orbit(c, (0,), 10, 10, 8), "center must be (x, y), two finite numbers of metres, got (0,)"),
    (lambda c: orbit(c, (0, 0), 10, float("inf"), 8), "altitude must be a finite number, got inf"),
    (lambda c: orbit(c, (0, 0), 10, 10, 2.5), "frames must be an integer from 2 to 1,000,000, got 2.5"),
    (lambda c: lawnmower(c, ((0, 0), (40, 40)), 10, 8, 20, fps=0), "fps must be a finite number > 0"),
    (lambda c: lawnmower(c, ((0, 0), (40, 40)), 10, 8, 1e-7), "spacing must be a number of metres >= 0.004 (at most 10,000 gaps between passes"),
    (lambda c: lawnmower(c, ((0, 0), (40, 40)), 10, 8, 20, pitch_deg=-120), "pitch_deg must be a number of degrees in [-90, 90]"),
    (lambda c: lawnmower(c, ((0, 0), (0, 40)), 10, 8, 20), "bounds must be (lo, hi), two finite (x, y) points with lo < hi"),
    (lambda c: spline_flythrough(c, ((0, 0, 2), (50, 50, 20)), 10, _RNG(0), fps=-10), "fps must be a finite number > 0, got -10"),
    (lambda c: spline_flythrough(c, ((0, 0, 2), (50, 50, 20)), 10, _RNG(0), fps=0), "fps must be a finite number > 0, got 0"),
    (lambda c: spline_flythrough(c, ((0, 0, 2), (50, 50, 20)), 10, _RNG(0), waypoints=0), "waypoints must be an integer from 2 to 1,000, got 0"),
    (lambda c: spline_flythrough(c, ((0, 0, 2), (50, 50, 20)), 10, _RNG(0), speed=float("nan")), "speed must be a finite number > 0"),
    (lambda c: spline_flythrough(c, ((0, 0, 2), (50, 50, 20)), 10, _RNG(0), attempts=0), "attempts must be an integer from 1 to 1,000"),
    (lambda c: spline_flythrough(c, ((0, 0), (50, 50)), 10, _RNG(0)), "bounds must be (lo, hi), two finite (x, y, z) points"),
    (lambda c: spline_flythrough(c, ((0, 0, 2), (50, 50, 20)), 10, 0), "rng must be a numpy.random.Generator"),
    (lambda c: random_walk(c, np.zeros(3), 5, _RNG(0)), "start must be a 4x4 rigid world_from_camera pose (pose must be a 4x4 matrix"),
    (lambda c: random_walk(c, np.eye(4), 5, _RNG(0), fps=0), "fps must be a finite number > 0, got 0"),
    (lambda c: random_walk(c, np.eye(4), True, _RNG(0)), "steps must be an integer from 1 to 1,000,000, got True"),
    (lambda c: modified_random_walk(c, np.eye(4), 5, _RNG(0), max_draws=10**9), "max_draws must be an integer from 1 to 100,000"),
    (lambda c: modified_random_walk(c, 2 * np.eye(4), 5, _RNG(0)), "start must be a 4x4 rigid world_from_camera pose"),
])
def test_bad_planner_parameters_give_one_line_naming_the_parameter_and_its_range(call, message):
    """Checked up front (trajectories/checks.py): no NaN timestamps, no identical poses, no
    IndexError or ZeroDivisionError, no endless loop."""
    with pytest.raises(ValueError) as info:
        call(_Free())
    text = str(info.value)
    assert message in text and "\n" not in text and not isinstance(info.value, TrajectoryError)


def test_parameters_at_the_stated_limits_are_accepted():
    """The edges of the ranges are valid: a clockwise half-turn per frame, the finest lawnmower
    spacing (10,000 passes), two waypoints, the steepest pitch."""
    c = _Free()
    t = orbit(c, (0, 0), 10, 10, 8, turns=-4)
    assert np.all(np.isfinite(t.timestamps)) and len({tuple(p.round(6)) for p in t.positions}) == 2
    t = lawnmower(c, ((0, 0), (40, 40)), 10, 50, 40 / 10_000, pitch_deg=-90)
    assert len(t) == 50 and np.all(np.diff(t.timestamps) > 0)
    t = spline_flythrough(c, ((0, 0, 2), (50, 50, 20)), 10, _RNG(0), waypoints=2, fps=1e-3 * 10_000)
    assert len(t) == 10 and np.all(np.diff(t.timestamps) > 0) and np.ptp(t.positions, axis=0).max() > 1
