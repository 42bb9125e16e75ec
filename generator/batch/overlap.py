"""The sinks' work beside the renderer's (issue #42; docs/architecture.md, "The frame loop").

While the renderer works on frame t + 1, frame t's outputs are written by the sinks in one
thread of their own: :class:`SinkThread` hands them every frame in order (each sink sees the
same frames in the same order as when called in the loop's thread, so the bytes written are
the same), with at most :data:`DEPTH` frames waiting (the loop blocks when they are: memory
stays bounded by DEPTH + 1 frames' outputs, about 30 MB each at 640x480 with every
modality). The sinks are closed in the loop's thread after the last frame was handed over.
A sink's error stops the handing over and is raised in the loop's thread at its next frame
(or when closing); a loop that fails stops the thread (:meth:`SinkThread.abandon`).

The trajectory loop overlaps when Cycles renders on a GPU (generator/batch/fly.py ``fly``):
there the CPU cores wait for the renderer and the sinks' work (about 0.5 CPU-seconds a
640x480 frame: docs/benchmarks.md, "Frame pipeline") is hidden behind it. On the CPU Cycles
uses every core, so the sinks' work is not hidden; it runs between renders as before.

Sinks must not use bpy (Blender belongs to the loop's thread) and must not change the
records they are handed: every sink of exporters/ is bpy-free and reads its records only.
"""

from __future__ import annotations

import queue
import threading

DEPTH = 2  # frames waiting for the sinks at most


class SinkThread:
    """Hands frames to ``sinks`` in a thread of its own (``threaded=False``: in the caller's,
    at once, as the loop did before)."""

    def __init__(self, sinks: list, threaded: bool = True, depth: int = DEPTH):
        self.sinks = sinks
        self.error: BaseException | None = None  # a sink's error, raised once in the loop's thread
        self.failed = False  # a sink failed: nothing more is written
        self.thread = None
        if threaded:
            self.queue: queue.Queue = queue.Queue(maxsize=depth)
            self.thread = threading.Thread(target=self._run, name="buildee-sinks", daemon=True)
            self.thread.start()

    def _run(self) -> None:
        while True:
            record = self.queue.get()
            if record is None:
                return
            if not self.failed:  # after an error the rest is drained, not written
                try:
                    self._hand(record)
                except BaseException as exc:  # raised in the loop's thread
                    self.error, self.failed = exc, True

    def _hand(self, record) -> None:
        for sink in self.sinks:
            sink.add_frame(record)

    def put(self, record) -> None:
        """Hand ``record`` to every sink (waits while DEPTH frames are waiting); raises a
        sink's earlier error."""
        self._raise()
        if self.thread is None:
            self._hand(record)
        else:
            self.queue.put(record)

    def close(self) -> None:
        """Wait for every frame handed over, then close the sinks in order; raises a sink's error."""
        self._stop()
        self._raise()
        for sink in self.sinks:
            sink.close()

    def abandon(self) -> None:
        """The loop failed: stop the thread once it has drained what it holds (nothing closed)."""
        self._stop()

    def _stop(self) -> None:
        if self.thread is not None:
            self.queue.put(None)
            self.thread.join()
            self.thread = None

    def _raise(self) -> None:
        if self.error is not None:
            error, self.error = self.error, None
            raise error
