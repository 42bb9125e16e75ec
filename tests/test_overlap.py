"""The sinks write frame t in a thread of their own while frame t + 1 renders
(generator/batch/overlap.py): the same bytes as writing between renders, frames handed over
in order, at most DEPTH waiting, a sink's error raised in the loop's thread, nothing left
running after a failure."""

import threading
import time

import numpy as np
import pytest

from generator import Simulator
from generator.batch.fly import fly
from generator.batch.overlap import DEPTH, SinkThread
from generator.geometry.camera import look_at
from test_modalities import animated_scene
from trajectories import Trajectory

T = 4


def test_the_threaded_sinks_write_the_same_bytes_as_the_loop_did(tmp_path):
    sim = Simulator(animated_scene(tmp_path / "scene.blend"), points_density=20, render_preset="preview")
    sim.configure_render(samples=2)
    eyes = [(-2.0 + 1.0 * t, -12.0 + 0.3 * t, 3.0 + 0.2 * t) for t in range(T)]
    traj = Trajectory(np.stack([look_at(e, (0.0, 0.0, 1.0)) for e in eyes]), np.arange(T) / 10.0, "test")
    for overlap in (True, False):
        fly(sim, traj, tmp_path / str(overlap) / "test", seed=0, overlap=overlap)
    threaded = sorted(p.relative_to(tmp_path / "True") for p in (tmp_path / "True").rglob("*") if p.is_file())
    serial = sorted(p.relative_to(tmp_path / "False") for p in (tmp_path / "False").rglob("*") if p.is_file())
    assert threaded == serial and len(threaded) > 4 * T
    for rel in threaded:
        assert (tmp_path / "True" / rel).read_bytes() == (tmp_path / "False" / rel).read_bytes(), rel


class Recorder:
    """A sink that keeps what it is handed, optionally waiting for ``gate`` at each frame."""

    def __init__(self, gate=None, fail_at=None):
        self.frames, self.closed, self.gate, self.fail_at = [], False, gate, fail_at
        self.threads = set()

    def add_frame(self, record):
        self.threads.add(threading.current_thread().name)
        if self.gate is not None:
            self.gate.wait(5)
        if record == self.fail_at:
            raise OSError(f"disk full at frame {record}")
        self.frames.append(record)

    def close(self):
        self.closed = True


def test_frames_reach_every_sink_in_order_in_one_thread_of_their_own():
    sinks = [Recorder(), Recorder()]
    worker = SinkThread(sinks)
    for i in range(50):
        worker.put(i)
    worker.close()
    assert all(s.frames == list(range(50)) and s.closed for s in sinks)
    assert all(s.threads == {"buildee-sinks"} for s in sinks)
    serial = Recorder()
    SinkThread([serial], threaded=False).put(7)
    assert serial.frames == [7] and serial.threads == {threading.current_thread().name}


def test_the_loop_waits_when_depth_frames_are_waiting():
    gate = threading.Event()
    worker = SinkThread([Recorder(gate)])
    handed = []

    def loop():
        for i in range(DEPTH + 3):
            worker.put(i)
            handed.append(i)

    thread = threading.Thread(target=loop)
    thread.start()
    time.sleep(0.5)
    # one frame in the sink, DEPTH waiting, the next one blocked
    assert len(handed) == DEPTH + 1
    gate.set()
    thread.join(5)
    worker.close()
    assert handed == list(range(DEPTH + 3))


def test_a_sinks_error_is_raised_in_the_loops_thread_and_nothing_is_closed():
    sink = Recorder(fail_at=3)
    worker = SinkThread([sink])
    with pytest.raises(OSError, match="disk full at frame 3"):
        for i in range(20):
            worker.put(i)
            time.sleep(0.01)
    worker.abandon()
    assert sink.frames == [0, 1, 2] and not sink.closed and worker.thread is None
    other = SinkThread([Recorder(fail_at=0)])
    other.put(0)
    with pytest.raises(OSError):
        other.close()
