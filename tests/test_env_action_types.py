"""A continuous action is real numbers: a value whose conversion to float64 drops or invents
information (complex, bool, strings, bytes, dates, Python objects) is refused in one line, by
the action's function and by the environment's step, which then leaves the camera where it was."""

import numpy as np
import pytest

from generator.envs.actions import continuous_targets
from generator.envs.exploration import ExplorationEnv

REFUSED = {
    "complex array": np.array([0.5j, 0, 0, 0, 0]),
    "complex with no imaginary part": np.array([0.5, 0, 0, 0, 0], dtype=np.complex64),
    "complex list": [0.5 + 1j, 0, 0, 0, 0],
    "booleans": np.array([True, False, False, False, True]),
    "strings": np.array(["1", "0", "0", "0", "0"]),
    "a string": "10000",
    "bytes": [b"1", b"0", b"0", b"0", b"0"],
    "Python objects": np.array([0.5, 0, 0, 0, 0], dtype=object),
    "dates": np.array(["2024-01-01"] * 5, dtype="datetime64[D]"),
    "a ragged list": [0.5, [0.0], 0, 0, 0],
}
ACCEPTED = {"float32": np.array([1, 0, 0, -1, 0], dtype=np.float32), "int8": np.array([1, 0, 0, -1, 0], np.int8),
            "float list": [1.0, 0.0, 0.0, -1.0, 0.0], "int list": [1, 0, 0, -1, 0],
            "float16": np.array([1, 0, 0, -1, 0], dtype=np.float16), "uint8 move": np.array([1, 0, 0, 0, 0], np.uint8)}


@pytest.mark.parametrize("name", sorted(REFUSED))
def test_an_action_that_is_not_real_numbers_is_refused_in_one_line(name):
    with pytest.raises(ValueError, match=r"^a continuous action is 5 finite real numbers \('forward', 'right', "
                                         r"'up', 'yaw', 'pitch'\) \(integers or floats\), got ") as err:
        continuous_targets(np.eye(4), REFUSED[name], 3.0, 22.5)
    assert "\n" not in str(err.value)


def test_real_actions_of_any_numeric_type_move_alike():
    moved = {name: continuous_targets(np.eye(4), a, 3.0, 22.5)[1] for name, a in ACCEPTED.items()}
    uint8 = moved.pop("uint8 move")
    assert not np.array_equal(uint8, np.eye(4)) and not np.array_equal(moved["float list"], uint8)
    assert all(np.array_equal(m, moved["float list"]) for m in moved.values())


def test_the_environment_refuses_a_complex_action_and_keeps_the_camera(tmp_path):
    from test_envs import room_scene

    env = ExplorationEnv(blend_files=[room_scene(tmp_path / "room.blend")], resolution=(24, 16), points_density=2.0,
                         action_space="continuous", step=1.0)
    obs, _ = env.reset(seed=0)
    for action in (REFUSED["complex array"], REFUSED["booleans"], REFUSED["strings"]):
        with pytest.raises(ValueError, match="^a continuous action is 5 finite real numbers") as err:
            env.step(action)
        assert "\n" not in str(err.value)
        assert np.array_equal(env.sim.get_world_from_camera(), obs["pose"])
    obs2, *_ = env.step(np.array([0.5, 0, 0, 0, 0], dtype=np.float32))  # a real action still moves
    assert np.allclose(obs2["pose"][:3, 3] - obs["pose"][:3, 3], 0.5 * np.array([*obs["pose"][:2, 2], 0.0])
                       / np.linalg.norm(obs["pose"][:2, 2]))
    env.close()
