"""Camera rigs: every trajectory also flown by cameras fixed to its own (bpy-free;
docs/cameras.md, "Rigs and stereo pairs").

The trajectory's own camera is the rig's reference: its pose at frame t is
``world_from_rig``. A rig camera ``name`` with extrinsics ``rig_from_camera`` (a 4x4 rigid
transform, OpenCV camera axes, metres) flies ``world_from_rig @ rig_from_camera`` at every
frame, in ``<kind>_<name>/``, with every output of a trajectory (tracks of the same point ids,
COLMAP, nerfstudio, COCO...); same K, lens, timestamps and frames of the site's animation.

``--stereo B`` is the rig of one camera, ``right`` = ``[I | (B, 0, 0)]``: a camera whose
extrinsics are a pure translation along the reference's x axis is its rectified partner (a
surface point at planar depth Z seen at (x, y) by the reference is seen at (x - fx B / Z, y)).

``--rig FILE`` reads a rig file (JSON)::

    {"cameras": [{"name": "right", "rig_from_camera": [[1, 0, 0, 0.12], [0, 1, 0, 0],
                                                       [0, 0, 1, 0], [0, 0, 0, 1]]},
                 {"name": "down", "rig_from_camera": [...]}]}

Names are 1 to 24 lower-case letters, digits or dashes; at most :data:`MAX_CAMERAS` cameras,
each within :data:`MAX_OFFSET_M` of the reference; rotations orthonormal with determinant +1
(generator/geometry/camera.py ``validate_rigid``). The rig is stored in the manifest's config (``rig``), so a seed folder says what
flew it; exporters/colmap_rig.py writes the rig's joint COLMAP model and transforms.json.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trajectories import Trajectory

from ..geometry.camera import matmul_exact, validate_rigid

MAX_CAMERAS = 8  # rig cameras besides the reference
MAX_OFFSET_M = 10.0  # the farthest a rig camera sits from the reference
NAME = re.compile(r"[a-z0-9][a-z0-9-]{0,23}")
STEREO_NAME = "right"  # --stereo's camera: <kind>_right/


class RigError(ValueError):
    """A rig that cannot fly (one line: what is wrong and what to do)."""


@dataclass(frozen=True)
class Rig:
    """The cameras fixed to each trajectory's own: ``names`` and ``rig_from_camera``
    ((C, 4, 4) float64), in the order they are flown."""

    names: tuple[str, ...]
    rig_from_camera: np.ndarray

    @classmethod
    def from_dict(cls, doc, where: str = "the rig") -> "Rig":
        """The Rig of ``{"cameras": [{"name", "rig_from_camera"}, ...]}``; RigError naming
        ``where`` and the first problem."""
        cameras = doc.get("cameras") if isinstance(doc, dict) else None
        if not isinstance(cameras, list) or not cameras or not all(isinstance(c, dict) for c in cameras):
            raise RigError(f"{where}: expected {{\"cameras\": [{{\"name\": ..., \"rig_from_camera\": 4x4}}, ...]}} "
                           "with at least one camera (docs/cameras.md)")
        if len(cameras) > MAX_CAMERAS:
            raise RigError(f"{where}: {len(cameras)} cameras; a rig holds at most {MAX_CAMERAS} besides the "
                           "trajectory's own")
        names, matrices = [], []
        for k, camera in enumerate(cameras):
            name = camera.get("name")
            if not isinstance(name, str) or not NAME.fullmatch(name):
                raise RigError(f"{where}: camera {k}'s name {name!r} must be 1 to 24 lower-case letters, digits or "
                               "dashes (its folder is <kind>_<name>)")
            if name in names:
                raise RigError(f"{where}: two cameras are named {name!r}; give each its own name")
            names.append(name)
            matrices.append(_rigid(camera.get("rig_from_camera"), f"{where}: camera {name!r}'s rig_from_camera"))
        return cls(tuple(names), np.stack(matrices))

    def as_dict(self) -> dict:
        """The rig file's document (what the manifest's config stores)."""
        return {"cameras": [{"name": n, "rig_from_camera": m.tolist()} for n, m in zip(self.names, self.rig_from_camera)]}

    def folders(self, kind: str) -> list[str]:
        """The rig cameras' trajectory folders for the trajectory ``kind``."""
        return [f"{kind}_{name}" for name in self.names]

    def baseline(self, k: int) -> float | None:
        """Camera ``k``'s baseline in metres when it is the reference's rectified partner (its
        extrinsics a translation along +x only), else None."""
        m = self.rig_from_camera[k]
        shift = np.eye(4)
        shift[0, 3] = m[0, 3]
        return float(m[0, 3]) if m[0, 3] > 0 and np.array_equal(m, shift) else None

    def cameras_of(self, kind: str, traj: Trajectory) -> list[tuple[str, Trajectory]]:
        """The rig cameras of ``traj`` (flown as ``kind``): [(folder, trajectory)]."""
        poses = np.asarray(traj.poses, np.float64)
        out = []
        for k, (name, folder) in enumerate(zip(self.names, self.folders(kind))):
            params = {"rig": {"reference": kind, "camera": name, "rig_from_camera": self.rig_from_camera[k].tolist()}}
            if self.baseline(k) is not None:
                params["stereo"] = {"left": kind, "baseline_m": self.baseline(k)}
            moved = matmul_exact(poses, self.rig_from_camera[k][None])
            out.append((folder, Trajectory(moved, np.asarray(traj.timestamps), traj.kind, list(traj.actions),
                                           dict(traj.params) | params)))
        return out


def _rigid(value, what: str) -> np.ndarray:
    """``value`` as a (4, 4) float64 rigid transform, or RigError naming ``what``."""
    try:
        m = validate_rigid(value)
    except ValueError as exc:
        raise RigError(f"{what}: {str(exc).replace('pose', 'the matrix', 1)}") from None
    offset = float(np.sqrt(m[0, 3] * m[0, 3] + m[1, 3] * m[1, 3] + m[2, 3] * m[2, 3]))
    if offset > MAX_OFFSET_M:
        raise RigError(f"{what} puts the camera {offset:.2f} m from the reference; a rig spans at most {MAX_OFFSET_M:g} m")
    return m + 0.0


def stereo_rig(baseline_m: float) -> Rig:
    """``--stereo B``: one camera, ``right``, B metres along the reference's x axis."""
    m = np.eye(4)
    m[0, 3] = baseline_m
    return Rig((STEREO_NAME,), m[None])


def read_rig(path: str | Path) -> Rig:
    """The rig of a rig file (JSON; see the module's docstring); RigError in one line."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except OSError as exc:
        raise RigError(f"cannot read the rig file {path}: {exc.strerror}") from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise RigError(f"the rig file {path} is not JSON: {exc}") from None
    return Rig.from_dict(doc, f"the rig file {path}")


def rig_of(stereo_baseline_m: float = 0.0, rig: dict | None = None) -> Rig | None:
    """The rig a run's config flies (``--stereo`` or ``--rig``), None for none."""
    if rig is not None:
        return Rig.from_dict(rig)
    return stereo_rig(stereo_baseline_m) if stereo_baseline_m > 0 else None


def rig_of_config(config: dict) -> Rig | None:
    """The rig of a manifest's config (its keys left out when there is none)."""
    return rig_of(float(config.get("stereo_baseline_m", 0.0)), config.get("rig"))


def with_rig_cameras(planned: list, rig: Rig | None) -> list:
    """``planned`` [(kind, trajectory)] followed by each one's rig cameras (none without a rig)."""
    if rig is None:
        return list(planned)
    return list(planned) + [camera for kind, traj in planned for camera in rig.cameras_of(kind, traj)]


def flown_kinds(kinds, rig: Rig | None) -> list[str]:
    """The trajectory folders of a run of ``kinds`` flying ``rig``."""
    kinds = [str(k) for k in kinds]
    return kinds + ([f for k in kinds for f in rig.folders(k)] if rig is not None else [])
