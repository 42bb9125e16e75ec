"""A rolling shutter: when each row of an image is read, and where a point lands in such an
image (bpy-free; docs/cameras.md, "Rolling shutter").

With a readout time R (seconds from the first row to the last), Cycles renders the rows top
to bottom: the pixels of row r (0 at the top) see the scene at the frame's time plus

    offset(r) = ((r + 1) / H - 1/2) R            (Cycles: ``1 - y / height`` of its bottom-up row y)

(the middle of their exposure when the shutter is also open). :class:`RollingCamera` holds
one trajectory's camera poses and moving objects' matrices at its frames (rigid motion between
frames: generator/geometry/motion.py ``MotionTrack``, as the LiDAR's) and gives:

- :meth:`RollingCamera.row_poses`: every row's camera pose at its own time;
- :meth:`RollingCamera.slices`: bands of rows within which the moving objects are placed once
  (at the band's middle time), so that no point of a moving object is more than
  ``motion_bound_m`` from where it was at its row's time (the ray-cast ground truth places
  objects per band; the camera is exact per row);
- :meth:`RollingCamera.project`: where points land in frame t's image: the row v whose time
  sees the point at row v (v = f(v), f(v) the row the point projects to with the camera and
  the point moved to row v's time; a row coordinate v reads its time as
  ((v + 1/2) / H - 1/2) R, which at the row's centre v = r + 1/2 is the row's own), solved
  by the secant method from the frame's time. A point that has not settled to 1e-6 px after
  :data:`MAX_ITERATIONS` steps (a camera turning so fast that no row sees it once) is
  reported as NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import project_camera_points

MAX_ITERATIONS = 40
SETTLED_PX = 1e-6
MAX_SLICES = 64
BOUND_M = 0.005  # the moving objects' placement error the slices aim for (metres)


@dataclass(frozen=True)
class RollingShutter:
    """``readout_s``: seconds from the first row's time to the last's; ``height``: rows."""

    readout_s: float
    height: int

    def row_offsets(self) -> np.ndarray:
        """(H,) seconds from the frame's time at which each row sees the scene."""
        r = np.arange(self.height, dtype=np.float64)
        return ((r + 1.0) / self.height - 0.5) * self.readout_s

    def offset_at(self, v: np.ndarray) -> np.ndarray:
        """Seconds from the frame's time of image row coordinate ``v`` (pixels, top edge 0),
        clipped to the image's rows."""
        v = np.clip(np.asarray(v, np.float64), 0.0, float(self.height))
        return ((v + 0.5) / self.height - 0.5) * self.readout_s

    def as_dict(self) -> dict:
        return {"readout_s": self.readout_s, "rows": "top to bottom",
                "row_time_s": "frame time + ((row + 1) / height - 1/2) x readout_s, row 0 at the top"}


class RollingCamera:
    """One trajectory seen through a rolling shutter: ``poses`` (T, 4, 4) world_from_camera
    and ``object_matrices`` (T, D, 4, 4) at the frame times ``times`` (T,) seconds."""

    def __init__(self, shutter: RollingShutter, times: np.ndarray, poses: np.ndarray, object_matrices: np.ndarray,
                 object_radius: np.ndarray | None = None):
        from .motion import MotionTrack

        self.shutter = shutter
        self.times = np.asarray(times, np.float64)
        self.camera = MotionTrack(self.times, poses)
        matrices = np.asarray(object_matrices, np.float64)
        self.objects = [MotionTrack(self.times, matrices[:, d]) for d in range(matrices.shape[1])]
        self.radius = np.zeros(len(self.objects)) if object_radius is None else np.asarray(object_radius, np.float64)

    def row_poses(self, index: int) -> np.ndarray:
        """(H, 4, 4) the camera's pose at every row's time of frame ``index``."""
        return self.camera.at(self.times[index] + self.shutter.row_offsets())

    def objects_at(self, index: int, offsets: np.ndarray) -> np.ndarray:
        """(M, D, 4, 4) the moving objects' matrices at frame ``index``'s time plus ``offsets`` (M,)."""
        t = self.times[index] + np.atleast_1d(np.asarray(offsets, np.float64))
        out = np.zeros((len(t), len(self.objects), 4, 4))
        for d, track in enumerate(self.objects):
            out[:, d] = track.at(t)
        return out

    def slices(self, index: int) -> tuple[list[tuple[int, int, float]], float]:
        """([(first row, end row, offset of the band's middle time)], motion bound in metres) of
        frame ``index``: enough equal bands of rows that the fastest object moves at most
        :data:`BOUND_M` in one (at most :data:`MAX_SLICES`)."""
        h, readout = self.shutter.height, self.shutter.readout_s
        start, end = self.times[index] - readout / 2, self.times[index] + readout / 2
        speed = max((track.speed_bound(r, start, end) for track, r in zip(self.objects, self.radius)), default=0.0)
        count = 1 if speed == 0.0 else int(min(MAX_SLICES, h, max(1, np.ceil(speed * readout / BOUND_M))))
        edges = np.linspace(0, h, count + 1).round().astype(int)
        offsets = self.shutter.row_offsets()
        bands = [(int(a), int(b), float((offsets[a] + offsets[b - 1]) / 2)) for a, b in zip(edges[:-1], edges[1:]) if b > a]
        longest = max(offsets[b - 1] - offsets[a] for a, b, _ in bands)
        return bands, speed * float(longest) / 2.0

    def project(self, index: int, local: np.ndarray, slot: np.ndarray, K: np.ndarray, lens) -> tuple[np.ndarray, np.ndarray]:
        """Where points land in frame ``index``'s image: ``local`` (N, 3) their coordinates
        (world for a static point, slot -1; the frame of moving object ``slot`` otherwise).
        Returns (uv (N, 2) pixels, planar depth (N,)) at the row time that sees each point;
        NaN where the iteration did not settle (see the module's docstring)."""
        local, slot = np.asarray(local, np.float64), np.asarray(slot, np.int64)
        n = len(local)
        # solve v = f(v), f(v) the row where the point lands with the camera and the point at
        # row v's time: the secant method on f(v) - v from v at the frame's time (the image's
        # middle) and the row the frame's time sees it at
        x0 = np.full(n, self.shutter.height / 2 - 0.5)
        uv, z = self._project_at(index, local, slot, self.shutter.offset_at(x0), K, lens)
        h0 = uv[:, 1] - x0
        x1 = uv[:, 1].copy()
        settled = np.abs(h0) <= SETTLED_PX
        live = np.flatnonzero(~settled & np.isfinite(x1))
        for _ in range(MAX_ITERATIONS):
            if not len(live):
                break
            new_uv, new_z = self._project_at(index, local[live], slot[live], self.shutter.offset_at(x1[live]), K, lens)
            uv[live], z[live] = new_uv, new_z
            h1 = new_uv[:, 1] - x1[live]
            done = np.abs(h1) <= SETTLED_PX
            settled[live[done]] = True
            with np.errstate(divide="ignore", invalid="ignore"):
                step = h1 * (x1[live] - x0[live]) / (h1 - h0[live])
            x0[live], h0[live] = x1[live], h1
            x1[live] = x1[live] - step
            live = live[~done & np.isfinite(x1[live])]
        uv[~settled], z[~settled] = np.nan, np.nan
        return uv, z

    def _project_at(self, index, local, slot, offsets, K, lens) -> tuple[np.ndarray, np.ndarray]:
        """Project each point with the camera and its object at frame ``index``'s time plus its
        own offset."""
        from .exact_kernels import batch_rows_times

        t = self.times[index] + offsets
        poses = self.camera.at(t) if len(t) else np.zeros((0, 4, 4))
        world = local.copy()
        for d in np.unique(slot[slot >= 0]):
            rows = np.flatnonzero(slot == d)
            m = self.objects[d].at(t[rows])
            rotated = np.empty((len(rows), 3))
            batch_rows_times(np.ascontiguousarray(local[rows]), np.ascontiguousarray(m[:, :3, :3].transpose(0, 2, 1)),
                             rotated)
            world[rows] = rotated + m[:, :3, 3]
        cam = np.empty_like(world)
        batch_rows_times(np.ascontiguousarray(world - poses[:, :3, 3]), np.ascontiguousarray(poses[:, :3, :3]), cam)
        return project_camera_points(cam, K, lens)

def pixel_rows_times(v: np.ndarray, rotations: np.ndarray, width: int) -> np.ndarray:
    """(H * W, 3): every pixel's vector ``v`` (H * W, 3) times its row's 3x3 ``rotations`` (H, 3, 3)."""
    from .exact_kernels import batch_rows_times

    per_pixel = np.ascontiguousarray(np.repeat(rotations, width, axis=0))
    out = np.empty((len(v), 3))
    batch_rows_times(np.ascontiguousarray(v, dtype=np.float64), per_pixel, out)
    return out

