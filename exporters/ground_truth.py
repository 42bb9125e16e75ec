"""Ground truth for offline scoring, in a seed's ``ground_truth/`` folder; read with no bpy.

- ``points.ply``: the labelled surface point cloud for scoring reconstructions, sampled
  uniformly on every surface at ``scoring_density`` points per square metre, objects placed
  as at the scene's first frame, except on faces resting on the ground (docs/scenes.md).
  Binary PLY, vertex properties x, y, z (float32, world metres), red, green, blue (uchar,
  the label's colour), label (int, id into the label table), instance (int, id into the
  object table), dynamic (uchar, 1 on moving objects), observable (uchar, 1 if visible from
  some observability viewpoint: ``generator.geometry.observability``).
- ``mesh.ply``: the scene's triangles at the first frame, world coordinates (float32),
  vertex colours by label; face properties label and instance.
- ``scene.h5``: everything needed to recompute visibility for any pose and frame: every
  rigid part in its own frame (static parts in world coordinates), the matrices of the
  dynamic parts at every frame of the animation, the simulator's surface points (with the
  normals the visibility rules use and their ``observable`` mask), the observability
  viewpoints, the camera and view limits of the generator.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, replace
from pathlib import Path

import h5py
import numpy as np

from generator.geometry.camera import apply_affine, turn_normals
from generator.geometry.lens import PINHOLE, Lens
from generator.geometry.parts import MeshPart
from generator.geometry.sampling import ground_height, outward_normals, sample_part
from generator.geometry.seeding import stream

from . import FORMAT_VERSION, VERSION_REMEDY

PLY_VERSION_COMMENT = "buildee ground truth format"  # the PLY header's comment, followed by the version
from .hdf5 import CHECKSUM, H5_ERRORS, create_file, damaged, dataset, reason, text_attribute
from .palette import label_colors
from .ply import PlyData, PlyError, read_ply, write_ply

FILES = ("points.ply", "mesh.ply", "scene.h5")
POINT_PROPERTIES = ("x", "y", "z", "red", "green", "blue", "label", "instance", "dynamic", "observable")  # points.ply
DEFAULT_SCORING_DENSITY = 100.0  # points per square metre: mean spacing ~0.1 m, mean NN distance ~0.05 m


def sample_scoring_points(parts: list[MeshPart], label_ids: dict[str, int], density: float, seed: int) -> dict:
    """Uniform samples on every part at ``density`` points/m^2 at the parts' current matrices:
    ``xyz`` (N, 3) float64 world metres, ``normals`` (N, 3) world outward unit normals (zero
    on open surfaces), ``label``, ``instance`` (N,) int32, ``dynamic`` (N,) bool.
    Seeded per part name, so adding a part does not move the samples of the others. Faces
    resting on the ground carry no points (``generator.geometry.sampling.contact_faces``)."""
    xyz, normals, label, instance, dynamic = [], [], [], [], []
    ground_z = ground_height(parts)
    for i, p in enumerate(parts):
        pts, face = sample_part(p, density, stream(seed, "scoring-points", p.name), ground_z)
        xyz.append(apply_affine(p.matrix, pts) if p.dynamic else pts)
        n = outward_normals(p, face)
        normals.append(turn_normals(p.matrix, n) if p.dynamic and len(n) else n)
        label.append(np.full(len(pts), label_ids[p.label], np.int32))
        instance.append(np.full(len(pts), i, np.int32))
        dynamic.append(np.full(len(pts), p.dynamic, bool))
    return {"xyz": np.concatenate(xyz), "normals": np.concatenate(normals), "label": np.concatenate(label),
            "instance": np.concatenate(instance), "dynamic": np.concatenate(dynamic)}


def write_ground_truth(folder: str | Path, parts: list[MeshPart], labels: list[str], surface: dict,
                       frames: np.ndarray, matrices: np.ndarray, fps: float, K: np.ndarray, width: int, height: int,
                       near: float, far: float, points_density: float, seed: int,
                       scoring_density: float = DEFAULT_SCORING_DENSITY, *, viewpoints: np.ndarray,
                       lens: Lens = PINHOLE) -> Path:
    """Write points.ply, mesh.ply and scene.h5 into ``folder``.

    ``parts`` as the Simulator holds them (``Simulator.scene_parts()``, matrices of the first
    frame); ``surface`` from ``Simulator.surface_sample()`` plus ``observable`` (its
    ``observable_points_mask``); ``viewpoints`` (K, 3) the observability viewpoints that mask
    used (the scoring cloud's mask uses them too); ``frames`` (F,) animation frame
    numbers and ``matrices`` (F, D, 4, 4) world_from_object of the D dynamic parts (in part
    order) at those frames; ``near``/``far`` the visibility depth limits (planar, metres);
    ``lens`` the camera's lens model (stored when it distorts).
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    label_ids = {name: i for i, name in enumerate(labels)}
    dyn = [i for i, p in enumerate(parts) if p.dynamic]
    frames = np.asarray(frames, np.int64)
    matrices = np.asarray(matrices, np.float64).reshape(len(frames), len(dyn), 4, 4)
    first = [p.matrix if not p.dynamic else matrices[0, dyn.index(i)] for i, p in enumerate(parts)]
    colors = label_colors(labels)
    comments = [f"{PLY_VERSION_COMMENT} {FORMAT_VERSION}", "units metres, world frame Z up",
                f"labels {json.dumps(labels)}"]

    placed = [p if not p.dynamic else _with_matrix(p, m) for p, m in zip(parts, first)]
    viewpoints = np.asarray(viewpoints, np.float64).reshape(-1, 3)
    observable = _write_points_ply(folder, placed, label_ids, colors, comments, scoring_density, seed, viewpoints)
    _write_mesh_ply(folder, placed, label_ids, colors, comments)
    _write_scene_h5(folder, parts, labels, label_ids, surface, frames, dyn, matrices, fps, K, width, height, near,
                    far, points_density, seed, scoring_density, viewpoints, observable, lens)
    return folder


def _write_points_ply(folder: Path, placed: list[MeshPart], label_ids: dict, colors: np.ndarray, comments: list[str],
                      scoring_density: float, seed: int, viewpoints: np.ndarray) -> np.ndarray:
    """points.ply: the scoring cloud of ``placed`` (parts at the first frame) with its
    observability flags, which it returns."""
    from generator.geometry.observability import observable_mask  # loads open3d (after bpy, if any)
    from generator.geometry.raycast import SceneGeometry

    pts = sample_scoring_points(placed, label_ids, scoring_density, seed)
    observable = observable_mask(SceneGeometry(placed), pts["xyz"], pts["normals"], pts["instance"], viewpoints)
    c = colors[pts["label"]]
    write_ply(folder / "points.ply", {
        "x": pts["xyz"][:, 0].astype(np.float32), "y": pts["xyz"][:, 1].astype(np.float32),
        "z": pts["xyz"][:, 2].astype(np.float32), "red": c[:, 0], "green": c[:, 1], "blue": c[:, 2],
        "label": pts["label"], "instance": pts["instance"], "dynamic": pts["dynamic"].astype(np.uint8),
        "observable": observable.astype(np.uint8)},
        comments=comments + [f"scoring_density {scoring_density} points per square metre", f"seed {seed}"])
    return observable


def _write_mesh_ply(folder: Path, placed: list[MeshPart], label_ids: dict, colors: np.ndarray,
                    comments: list[str]) -> None:
    """mesh.ply: every part's triangles at the first frame (``placed``: the parts with their
    first frame's matrices)."""
    verts, faces, vlabel, flabel, finst, offset = [], [], [], [], [], 0
    for i, p in enumerate(placed):
        verts.append(apply_affine(p.matrix, p.vertices) if p.dynamic else p.vertices)
        faces.append(p.faces + offset)
        offset += len(p.vertices)
        vlabel.append(np.full(len(p.vertices), label_ids[p.label], np.int32))
        flabel.append(np.full(len(p.faces), label_ids[p.label], np.int32))
        finst.append(np.full(len(p.faces), i, np.int32))
    v = np.concatenate(verts).astype(np.float32)
    vc = colors[np.concatenate(vlabel)]
    write_ply(folder / "mesh.ply", {"x": v[:, 0], "y": v[:, 1], "z": v[:, 2], "red": vc[:, 0], "green": vc[:, 1],
                                    "blue": vc[:, 2]},
              faces=np.concatenate(faces), face={"label": np.concatenate(flabel), "instance": np.concatenate(finst)},
              comments=comments + ["objects at the first animation frame"])


def _write_scene_h5(folder: Path, parts: list[MeshPart], labels: list[str], label_ids: dict, surface: dict,
                    frames: np.ndarray, dyn: list[int], matrices: np.ndarray, fps: float, K: np.ndarray, width: int,
                    height: int, near: float, far: float, points_density: float, seed: int, scoring_density: float,
                    viewpoints: np.ndarray, observable: np.ndarray, lens: Lens = PINHOLE) -> None:
    """scene.h5: the parts, their animation, the surface points, observability and camera."""
    with create_file(folder / "scene.h5") as f:  # checksummed (exporters/hdf5.py): damage fails to read
        f.attrs.update({"format_version": FORMAT_VERSION, "labels": text_attribute(json.dumps(labels)), "fps": float(fps),
                        "seed": int(seed), "points_density": float(points_density),
                        "scoring_density": float(scoring_density),
                        "conventions": "metres; world Z up; static parts in world coordinates, dynamic parts in "
                                       "their object frame; matrices world_from_object; camera OpenCV; "
                                       "near < planar depth <= far"})
        g = f.create_group("parts")
        kw = {"compression": "gzip", "compression_opts": 4, **CHECKSUM}
        g.create_dataset("vertices", data=np.concatenate([p.vertices for p in parts]).astype(np.float64), **kw)
        g.create_dataset("faces", data=np.concatenate([p.faces for p in parts]).astype(np.int32), **kw)
        dataset(g, "vertex_offsets", np.cumsum([0] + [len(p.vertices) for p in parts]).astype(np.int64))
        dataset(g, "face_offsets", np.cumsum([0] + [len(p.faces) for p in parts]).astype(np.int64))
        dataset(g, "name", np.array([p.name for p in parts], dtype=object))  # fixed-length UTF-8 bytes
        dataset(g, "source", np.array([p.source for p in parts], dtype=object))
        dataset(g, "label", np.array([label_ids[p.label] for p in parts], np.int32))
        dataset(g, "dynamic", np.array([p.dynamic for p in parts], bool))
        dataset(g, "closed", np.array([p.closed for p in parts], bool))
        dataset(g, "outward", np.array([p.outward for p in parts], np.int8))
        dataset(g, "scenery", np.array([p.scenery for p in parts], bool))
        a = f.create_group("animation")
        dataset(a, "frames", np.asarray(frames))
        dataset(a, "dynamic_parts", np.asarray(dyn, np.int32))
        a.create_dataset("world_from_object", data=matrices, **kw)
        s = f.create_group("surface_points")
        s.attrs["density"] = float(points_density)
        for key in ("local", "local_normals"):
            s.create_dataset(key, data=np.asarray(surface[key], np.float64), **kw)
        s.create_dataset("part", data=np.asarray(surface["part"], np.int32), **kw)
        s.create_dataset("label", data=np.asarray(surface["labels"], np.int32), **kw)
        s.create_dataset("observable", data=np.asarray(surface["observable"], bool), **kw)
        o = f.create_group("observability")
        dataset(o, "viewpoints", np.asarray(viewpoints))
        o.attrs.update({"rule": "visible from at least one viewpoint, looking in any direction, under the "
                                "simulator's visibility rules with no depth limit, objects at the first frame "
                                "(generator/geometry/observability.py)",
                        "scoring_points_observable": int(observable.sum()),
                        "scoring_points": int(len(observable))})
        cam = f.create_group("camera")
        dataset(cam, "K", np.asarray(K, np.float64))
        cam.attrs.update({"width": int(width), "height": int(height), "near": float(near), "far": float(far)})
        if not lens.ideal:  # generator/geometry/lens.py Lens.as_dict; absent: the ideal pinhole
            cam.attrs["lens"] = text_attribute(json.dumps(lens.as_dict()))


def write_simulator_ground_truth(sim, folder: str | Path, seed: int,
                                 scoring_density: float = DEFAULT_SCORING_DENSITY) -> Path:
    """:func:`write_ground_truth` for a ``generator.Simulator``'s scene: visits every frame of
    its animation for the dynamic matrices and leaves it at the first frame."""
    first, last = sim.frame_range
    frames = np.arange(first, last + 1)
    matrices = []
    for f in frames:
        sim.set_frame(int(f))
        matrices.append(sim.dynamic_object_matrices())
    from generator.geometry.observability import default_viewpoints

    sim.set_frame(first)
    surface = sim.surface_sample() | {"observable": sim.observable_points_mask}
    return write_ground_truth(folder, sim.scene_parts(), sim.labels, surface, frames, np.stack(matrices),
                              sim.fps, sim.K, sim.width, sim.height, sim.clip_start,
                              min(sim.clip_end, sim.max_pcl_depth), sim.points_density, seed, scoring_density,
                              viewpoints=default_viewpoints(sim.spawn_points), lens=sim.lens)


def _lens(attrs, folder: Path) -> Lens:
    """scene.h5's camera lens (the ideal pinhole where none is stored)."""
    if "lens" not in attrs:
        return PINHOLE
    try:
        return Lens.from_dict(json.loads(attrs["lens"]))
    except (ValueError, TypeError) as exc:
        raise GroundTruthError(f"{folder / 'scene.h5'}: camera lens: {exc}; regenerate the seed") from None


def _with_matrix(part: MeshPart, matrix: np.ndarray) -> MeshPart:
    return replace(part, matrix=np.asarray(matrix, np.float64))


def check_ply_version(path: str | Path, comments: list[str]) -> None:
    """Refuse a points.ply / mesh.ply whose header does not state this format version."""
    stated = [c[len(PLY_VERSION_COMMENT):].strip() for c in comments if c.startswith(PLY_VERSION_COMMENT)]
    if stated != [FORMAT_VERSION]:
        raise GroundTruthError(f"{path}: ground-truth format {stated[0] if stated else 'not stated'}, this reader "
                               f"reads {FORMAT_VERSION} ({VERSION_REMEDY})")


class GroundTruthError(ValueError):
    """A ground-truth folder or file that cannot be used (the message says why)."""


def _read_versioned_ply(path: Path) -> PlyData:
    """A ground-truth PLY of this format version; else a one-line :class:`GroundTruthError`."""
    try:
        data = read_ply(path)
    except PlyError as exc:
        raise GroundTruthError(f"{exc}; regenerate this seed with python -m generator") from None
    check_ply_version(path, data.comments)
    return data


def read_points(folder: str | Path) -> PlyData:
    """The ground-truth scoring cloud ``folder/points.ply`` (``folder``: a seed's ground_truth/
    folder, or a timeline stage's ``phase_K/ground_truth/``): the vertex properties of
    :data:`POINT_PROPERTIES` (module docstring) and the header comments (format version, units,
    label table, scoring density, seed). A missing or damaged file, one of another format
    version or one without one of those properties raises a one-line :class:`GroundTruthError`
    naming the file."""
    path = Path(folder) / "points.ply"
    points = _read_versioned_ply(path)
    missing = [k for k in POINT_PROPERTIES if k not in points.vertex]
    if missing:
        raise GroundTruthError(f"{path}: no {', '.join(missing)} property; not a ground-truth cloud of "
                               "python -m generator, regenerate this seed")
    return points


def read_mesh(folder: str | Path) -> PlyData:
    """The ground-truth mesh ``folder/mesh.ply`` (``folder``: a seed's ground_truth/ folder):
    vertices x, y, z (float32 world metres) coloured by label, ``faces`` (F, 3) and the face
    properties label and instance. A missing or damaged file, one of another format version or
    one without faces raises a one-line :class:`GroundTruthError` naming the file."""
    path = Path(folder) / "mesh.ply"
    mesh = _read_versioned_ply(path)
    if mesh.faces is None:
        raise GroundTruthError(f"{path}: no faces; not the ground-truth mesh of python -m generator, "
                               "regenerate this seed")
    return mesh


@dataclass
class GroundTruthScene:
    """A scene's ground truth read from ``scene.h5`` (see the module docstring).

    ``parts``: rigid parts with matrices of the first frame; ``frames`` (F,) animation frame
    numbers; ``matrices`` (F, D, 4, 4) of the dynamic parts ``dynamic_parts`` (D,);
    ``surface``: local, local_normals, part, label and (when stored) observable; ``viewpoints``
    (K, 3) of the observability mask (None in files without one); camera ``K``, ``width``, ``height`` and
    visibility limits ``near``, ``far`` (metres); ``fps``; ``labels``; ``lens`` the camera's lens
    model (generator/geometry/lens.py).
    """

    folder: Path
    labels: list[str]
    parts: list[MeshPart]
    frames: np.ndarray
    dynamic_parts: np.ndarray
    matrices: np.ndarray
    surface: dict
    K: np.ndarray
    width: int
    height: int
    near: float
    far: float
    fps: float
    seed: int
    viewpoints: np.ndarray | None = None
    lens: Lens = PINHOLE

    def frame_index(self, frame: int) -> int:
        """Row of ``matrices`` for an animation frame (frames outside the range clamp to its ends)."""
        return int(np.clip(int(frame) - int(self.frames[0]), 0, len(self.frames) - 1))

    def matrices_at(self, frame: int) -> dict[int, np.ndarray]:
        """world_from_object of each dynamic part at ``frame``, keyed by part index."""
        row = self.matrices[self.frame_index(frame)]
        return {int(i): row[k] for k, i in enumerate(self.dynamic_parts)}

    def scoring_points(self) -> PlyData:
        """The labelled scoring cloud (points.ply, read by :func:`read_points`)."""
        return read_points(self.folder)


def read_ground_truth(folder: str | Path) -> GroundTruthScene:
    """Read ``folder/scene.h5`` (a seed folder or its ground_truth/ folder)."""
    folder = Path(folder)
    if (folder / "ground_truth").is_dir():
        folder = folder / "ground_truth"
    missing = [name for name in FILES if not (folder / name).is_file()]
    if missing:
        raise GroundTruthError(f"{folder}: incomplete ground truth, missing {', '.join(missing)} "
                               f"(regenerate the seed with python -m generator)")
    try:
        with h5py.File(folder / "scene.h5", "r") as f:
            version = f.attrs.get("format_version")
            if version != FORMAT_VERSION:
                raise GroundTruthError(f"{folder / 'scene.h5'}: ground-truth format {version!r}, this reader reads "
                                       f"{FORMAT_VERSION} ({VERSION_REMEDY})")
            g = f["parts"]
            V, F = g["vertices"][()], g["faces"][()]
            vo, fo = g["vertex_offsets"][()], g["face_offsets"][()]
            names = [n.decode() if isinstance(n, bytes) else n for n in g["name"][()]]
            sources = [n.decode() if isinstance(n, bytes) else n for n in g["source"][()]]
            labels = json.loads(f.attrs["labels"])
            a, s, cam = f["animation"], f["surface_points"], f["camera"]
            frames, dyn, mats = a["frames"][()], a["dynamic_parts"][()], a["world_from_object"][()]
            dynamic, closed, outward, label = (g[k][()] for k in ("dynamic", "closed", "outward", "label"))
            scenery = g["scenery"][()] if "scenery" in g else np.zeros(len(names), bool)  # written since #39
            slot = {int(p): k for k, p in enumerate(dyn)}
            parts = [MeshPart(name=name, label=labels[int(label[i])], vertices=V[vo[i]:vo[i + 1]],
                              faces=F[fo[i]:fo[i + 1]].astype(np.int64), dynamic=bool(dynamic[i]),
                              matrix=mats[0, slot[i]].copy() if dynamic[i] else np.eye(4), closed=bool(closed[i]),
                              outward=int(outward[i]), source=sources[i], scenery=bool(scenery[i]))
                     for i, name in enumerate(names)]
            surface = {k: s[k][()] for k in ("local", "local_normals", "part", "label", "observable") if k in s}
            viewpoints = f["observability/viewpoints"][()] if "observability" in f else None
            return GroundTruthScene(folder, labels, parts, frames, dyn, mats, surface, cam["K"][()],
                                    int(cam.attrs["width"]), int(cam.attrs["height"]), float(cam.attrs["near"]),
                                    float(cam.attrs["far"]), float(f.attrs["fps"]), int(f.attrs["seed"]), viewpoints,
                                    _lens(cam.attrs, folder))
    except GroundTruthError:
        raise
    except H5_ERRORS as exc:  # a failed checksum, or damaged metadata wherever h5py looks
        raise GroundTruthError(str(damaged(folder / "scene.h5", reason(exc)))) from None
