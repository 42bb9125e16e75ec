"""A LiDAR sweep cast into the scene's exact triangles, over time (bpy-free; docs/lidar.md).

:class:`Scanner` holds one scene (the rigid parts the Simulator already builds:
generator/geometry/raycast.py ``SceneGeometry``, static parts in one Embree structure, moving
ones in another) with each part's class and object ids and its faces' optics.
:meth:`Scanner.sweep` fires one sweep of a sensor (generator/lidar/sensors.py) carried by a
body whose pose over time is a :class:`generator.geometry.motion.MotionTrack`:

1. every beam leaves from the sensor's pose at its own firing time (the body's pose then,
   times the mount's rotation);
2. moving objects are placed at the middle of the time slice the beam falls in: the sweep
   is cut into :meth:`Scanner.slices` equal slices, so that no point of a moving object is
   more than ``speed x slice / 2`` from where it was when the beam met it (the bound is
   returned with the sweep and kept under the range noise's sigma, or 1 cm without noise);
3. a beam stops at the first opaque face; glass passes it on (generator/lidar/physics.py);
4. the range gets its noise, the return its intensity, and the detection rules drop what a
   real sensor would not report.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..geometry.camera import affine_inverse, apply_affine, matmul_exact, rows_times
from ..geometry.raycast import SceneGeometry
from ..geometry.structure import near_edge_tol
from ..geometry.seeding import stream
from . import kernels, physics
from ..geometry.motion import MotionTrack
from .returns import Scan
from .sensors import body_from_sensor, emission

MAX_SLICES = 256


@dataclass(frozen=True)
class Sweep:
    """A sweep's returns, their float64 world positions ``world`` (N, 3) at the returns' own
    times (the scan's files hold float32: a few micrometres of rounding at tens of metres),
    ``beam`` (N,) int64 the index of each return's beam in the sensor's emission (its
    ``directions``, ``ring``, ``time``), and its motion bound: no return is further than
    ``motion_bound_m`` metres from where the moving surface it met was at the return's time."""

    scan: Scan
    world: np.ndarray
    beam: np.ndarray
    motion_bound_m: float
    slices: int


class Scanner:
    """Sweeps sensors through one scene. ``geometry``: its rigid parts; ``label_of_part``,
    ``instance_of_part`` (P,): each part's class id and object id; ``seed``: the noise's
    random streams are (seed, "lidar", sensor name, sweep index)."""

    def __init__(self, geometry: SceneGeometry, label_of_part: np.ndarray, instance_of_part: np.ndarray, seed: int):
        self.geometry = geometry
        self.label_of_part = np.asarray(label_of_part, dtype=np.int64)
        self.instance_of_part = np.asarray(instance_of_part, dtype=np.int64)
        if max(self.label_of_part.max(initial=0), self.instance_of_part.max(initial=0)) > 0xFFFF:
            raise ValueError("a LiDAR scan stores class and object ids in 16 bits: this scene has more than 65,535 "
                             "objects or classes; scan a smaller scene")
        self.seed = seed
        # every part's faces' optics in one array: part i's face f at first_face[i] + f
        self.first_face = np.cumsum([0] + [len(p.faces) for p in geometry.parts])[:-1].astype(np.int64)
        self.reflectivity = np.concatenate([np.zeros(0)] + [
            _face_values(p.face_reflectivity, len(p.faces), physics.DEFAULT_REFLECTIVITY, np.float64) for p in geometry.parts])
        self.transparent = np.concatenate([np.zeros(0, bool)] + [
            _face_values(p.face_transparent, len(p.faces), False, bool) for p in geometry.parts])
        self.radius = {i: geometry.parts[i].radius() for i in geometry.dynamic_index}
        self._glass_split = None

    @classmethod
    def of_parts(cls, parts, label_of_part, seed: int) -> "Scanner":
        """A Scanner over ``parts`` (a scene's rigid parts in object-id order: object id =
        position) with their class ids ``label_of_part``: its own Embree structures."""
        return cls(SceneGeometry(parts), np.asarray(label_of_part, dtype=np.int64), np.arange(len(parts)), seed)

    def slices(self, sensor, objects: dict[int, MotionTrack], start_time_s: float = 0.0) -> tuple[int, float]:
        """(slices, motion bound in metres) of a sweep of ``sensor`` starting at
        ``start_time_s`` among ``objects`` (part index -> its track): enough equal slices that
        the fastest object (over the frames the sweep spans) moves at most the range noise's
        sigma (1 cm without noise) in one, at most :data:`MAX_SLICES` (a long sweep among
        fast machines, a terrestrial scan's 30 s, may then be bounded above the noise: the
        bound is recorded with every sweep)."""
        duration = 1.0 / sensor.rate_hz
        end = start_time_s + duration
        speed = max((track.speed_bound(self.radius.get(i, 0.0), start_time_s, end) for i, track in objects.items()),
                    default=0.0)
        if speed == 0.0:
            return 1, 0.0
        allowed = sensor.range_noise_sigma_m if sensor.range_noise_sigma_m > 0 else 0.01
        n = int(min(MAX_SLICES, max(1, np.ceil(speed * duration / allowed))))
        return n, speed * duration / n / 2.0

    def sweep(self, sensor, index: int, start_time_s: float, body: MotionTrack,
              objects: dict[int, MotionTrack] | None = None, noise: bool = True) -> Sweep:
        """Sweep number ``index`` of ``sensor`` starting at ``start_time_s`` (seconds on the
        tracks' clock), carried by ``body``, with the moving parts on their ``objects`` tracks
        (part index -> track); ``noise=False`` reports exact ranges."""
        objects = objects or {}
        beams = emission(sensor, index)
        n = len(beams.time)
        mount = np.eye(4)
        mount[:3, :3] = body_from_sensor(sensor)
        origin, direction = _world_rays(body, mount, start_time_s, beams)
        count, bound = self.slices(sensor, objects, start_time_s)
        edges = np.linspace(0.0, 1.0 / sensor.rate_hz, count + 1)
        middles = start_time_s + (edges[:-1] + edges[1:]) / 2.0
        at_middles = {i: track.at(middles) for i, track in objects.items()}
        placed = [{i: poses[k] for i, poses in at_middles.items()} for k in range(count)]  # per slice: its middle's
        if count == 1:
            which = np.zeros(n, dtype=np.int64)
            if objects:
                self.geometry.set_matrices(placed[0])
            hits = self._cast(origin, direction)
        else:
            which = np.clip(np.searchsorted(edges, beams.time, side="right") - 1, 0, count - 1)
            hits = _Hits.empty(n)
            for k in range(count):
                rows = np.flatnonzero(which == k)
                if len(rows):
                    self.geometry.set_matrices(placed[k])
                    hits.put(rows, self._cast(np.take(origin, rows, axis=0), np.take(direction, rows, axis=0)))
        reference = matmul_exact(body.at(start_time_s)[0], mount)
        frozen = _Freeze(which, placed, {i: track.at(start_time_s)[0] for i, track in objects.items()})
        met = int(np.count_nonzero(hits.part >= 0))
        draws = stream(self.seed, "lidar", sensor.name, index).standard_normal(met) if noise else np.zeros(met)
        scan, world, beam = self._scan(sensor, index, start_time_s, beams, draws, (origin, direction, hits),
                                       reference, frozen)
        return Sweep(scan, world, beam, bound, count)

    def _cast(self, origin: np.ndarray, direction: np.ndarray) -> "_Hits":
        """First opaque hits of the world rays (``origin``, ``direction``: (M, 3)), through up
        to MAX_GLASS_FACES glass faces."""
        hits = _Hits(*self.geometry.cast_faces(origin, direction), np.zeros(len(origin), dtype=np.int64))
        live = kernels.glass_hits(hits.part, hits.face, self.first_face, self.transparent)  # first hit: a pane
        if len(live):
            hits.put(live, self._through_glass(np.take(origin, live, axis=0), np.take(direction, live, axis=0)))
        return hits

    def _through_glass(self, origin: np.ndarray, direction: np.ndarray) -> "_Hits":
        """Hits of rays that first meet glass: the first hit among the scene's opaque faces
        (exact, as every hit), and the glass faces crossed before it (Embree's list of every
        glass face along the ray, with its float32 distance; a glass face up to the hit's
        tolerance behind it, a pane's back face flush on a wall, counts as crossed); past
        MAX_GLASS_FACES: lost."""
        split = self._split()
        t, part, face, normal = split.opaque.cast_faces(origin, direction)
        met = part >= 0
        face[met] = split.opaque_face[split.opaque_first[part[met]] + face[met]]
        panes = split.glass.crossings(origin, direction, t + near_edge_tol(t))  # a pane flush on a wall: crossed
        lost = panes > physics.MAX_GLASS_FACES
        part[lost], t[lost], face[lost] = -1, np.inf, -1
        return _Hits(t, part, face, normal, panes)

    def _split(self) -> "_GlassSplit":
        """The scene's opaque faces and its glass faces as two geometries (built on first use),
        their moving parts placed as the scene's are."""
        if self._glass_split is None:
            self._glass_split = _GlassSplit(self.geometry.parts, self.transparent, self.first_face)
        placed = {i: self.geometry.parts[i].matrix for i in self.geometry.dynamic_index}
        self._glass_split.opaque.set_matrices(placed)
        self._glass_split.glass.set_matrices(placed)
        return self._glass_split

    def _scan(self, sensor, index, start_time_s, beams, draws, cast, reference: np.ndarray,
              frozen: "_Freeze") -> tuple[Scan, np.ndarray, np.ndarray]:
        """The sweep's detected returns as a :class:`Scan`, their float64 world points and
        their beams; ``cast``: every beam's world ray (origin, direction) and its hit."""
        origin, direction, hits = cast
        n = len(hits.part)
        rows, measured, exact, value = np.empty(n, np.int64), np.empty(n), np.empty(n), np.empty(n, np.float32)
        m = physics.returns(hits.part, hits.face, self.first_face, self.reflectivity, hits.normal, direction,
                            hits.panes, hits.range, draws, physics.rules(sensor), rows, measured, exact, value)
        rows, measured, exact, value = rows[:m], measured[:m], exact[:m], value[:m]
        part = hits.part[rows]
        world, xyz = np.empty((m, 3)), np.empty((m, 3), dtype=np.float32)
        deskewed, surface = np.empty((m, 3), dtype=np.float32), np.empty((m, 3), dtype=np.float32)
        to_sensor = affine_inverse(reference)
        kernels.return_points(rows, origin, direction, beams.directions, measured, exact, to_sensor, world, xyz,
                              deskewed, surface)
        moved = np.flatnonzero(np.isin(part, list(frozen.reference)))
        if len(moved):  # returns on moving objects: their points with the scene frozen at the reference time
            at = rows[moved], part[moved]
            deskewed[moved] = apply_affine(to_sensor, frozen.at_reference(world[moved], *at))
            surface[moved] = apply_affine(to_sensor, frozen.at_reference(
                origin[rows[moved]] + exact[moved, None] * direction[rows[moved]], *at))
        scan = Scan(sensor.name, index, float(start_time_s), reference, xyz, deskewed, value,
                    beams.ring[rows].astype(np.uint16), beams.time[rows].astype(np.float32),
                    self.label_of_part[part].astype(np.uint16), self.instance_of_part[part].astype(np.uint16),
                    xyz_exact=surface)
        return scan, world, rows


def _world_rays(body: MotionTrack, mount: np.ndarray, start_time_s: float, beams) -> tuple[np.ndarray, np.ndarray]:
    """(origins, directions) (N, 3) in the world of every beam, each from the sensor's pose at
    its firing time (computed once per firing time: a spinning sensor's column shares one)."""
    poses = np.ascontiguousarray(matmul_exact(body.at(start_time_s + beams.firing_times), mount[None]))
    n = len(beams.time)
    origin, direction = np.empty((n, 3)), np.empty((n, 3))
    kernels.posed_rays(beams.directions, beams.firing, poses, origin, direction)
    return origin, direction


class _GlassSplit:
    """The faces of ``parts`` split into an opaque geometry and a glass one (``transparent``:
    every part's faces' flags, part p's face f at ``first_face[p] + f``): part p's opaque face
    k is its face ``opaque_face[opaque_first[p] + k]``."""

    def __init__(self, parts, transparent: np.ndarray, first_face: np.ndarray):
        opaque, glass, kept = [], [], []
        for p, part in enumerate(parts):
            flags = transparent[first_face[p]:first_face[p] + len(part.faces)]
            kept.append(np.flatnonzero(~flags))
            opaque.append(_faces_of(part, kept[-1]))
            glass.append(_faces_of(part, np.flatnonzero(flags)))
        self.opaque, self.glass = SceneGeometry(opaque), SceneGeometry(glass)
        self.opaque_face = np.concatenate([np.zeros(0, np.int64)] + kept).astype(np.int64)
        self.opaque_first = np.cumsum([0] + [len(k) for k in kept])[:-1].astype(np.int64)


def _faces_of(part, faces: np.ndarray):
    """``part`` with only its faces ``faces`` (indices), same vertices and pose."""
    return replace(part, faces=part.faces[faces], matrix=part.matrix.copy(), closed=False,
                   face_reflectivity=None, face_transparent=None)


class _Freeze:
    """Moves returns on moving objects to where their surface point was at the sweep's
    reference time: p_ref = M(t_ref) M(t_slice)^-1 p (the scene frozen at the reference time)."""

    def __init__(self, slice_of_beam: np.ndarray, placed: list[dict], reference: dict):
        self.slice_of_beam, self.placed, self.reference = slice_of_beam, placed, reference

    def at_reference(self, world: np.ndarray, rows: np.ndarray, part: np.ndarray) -> np.ndarray:
        out = world.copy()
        for i, ref in self.reference.items():
            for k in np.unique(self.slice_of_beam[rows[part == i]]):
                sel = np.flatnonzero((part == i) & (self.slice_of_beam[rows] == k))
                move = matmul_exact(ref, affine_inverse(self.placed[k][i]))
                out[sel] = apply_affine(move, world[sel])
        return out


class _Hits:
    """Per beam: its first opaque hit (part -1: none), range (metres, inf: none), face, world
    normal (float32), and the glass faces it passed."""

    def __init__(self, range_m, part, face, normal, panes):
        self.range, self.part, self.face, self.normal, self.panes = range_m, part, face, normal, panes

    @classmethod
    def empty(cls, n: int) -> "_Hits":
        return cls(np.full(n, np.inf), np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64),
                   np.zeros((n, 3), dtype=np.float32), np.zeros(n, dtype=np.int64))

    def put(self, rows: np.ndarray, other: "_Hits") -> None:
        """Beams ``rows`` take ``other``'s hits (one per row, in order)."""
        self.range[rows], self.part[rows], self.face[rows] = other.range, other.part, other.face
        self.normal[rows], self.panes[rows] = other.normal, other.panes


def _face_values(values, count: int, default, dtype) -> np.ndarray:
    """A part's per-face optics, or ``default`` for every face."""
    if values is None:
        return np.full(count, default, dtype=dtype)
    values = np.asarray(values, dtype=dtype)
    if values.shape != (count,):
        raise ValueError(f"per-face LiDAR optics hold {values.shape} values for {count} faces")
    return values
