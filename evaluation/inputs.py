"""Reading and checking what a participant submits: point clouds with optional labels, and
camera trajectories. Every problem raises :class:`InputError` with a one-line message that
says what is wrong and what to do."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from exporters.hdf5 import DamagedFileError
from exporters.jsonfile import read_checked_bytes
from exporters.ply import PlyData, PlyError, read_ply
from generator.checks import check_number, items
from trajectories.arrays import ArrayFileError, load_arrays


class InputError(ValueError):
    """Bad input to the evaluation (one line: what is wrong, what to do)."""


def check_metres(name: str, value, low: float = 0.0, *, or_equal: bool = False) -> float:
    """``value`` as a float if it is a finite number of metres above ``low`` (``or_equal``:
    or equal to it); else an :class:`InputError` naming ``name``, the range and the value."""
    side = "non-negative" if or_equal else "positive"
    valid = f"a {side} number of metres" if low == 0 else f"a number of metres {'>=' if or_equal else 'above'} {low:g}"
    try:
        return check_number(name, value, low, open_low=not or_equal, valid=valid)
    except ValueError as exc:
        raise InputError(str(exc)) from None


def check_sweep(sweep) -> tuple[float, ...]:
    """The thresholds of a precision/recall sweep, each checked as :func:`check_metres` checks
    one (what the CLI's ``--sweep`` accepts); an empty sweep is allowed (no sweep figures)."""
    thresholds = items(sweep)
    if thresholds is None:
        raise InputError(f"sweep must be a sequence of positive numbers of metres, got {sweep!r}")
    return tuple(check_metres(f"sweep[{i}]", t) for i, t in enumerate(thresholds))


def load_array_file(path: Path, keys: tuple[str, ...] | None = None, check=None,
                    expansion: bool = True) -> np.ndarray | dict[str, np.ndarray]:
    """:func:`trajectories.arrays.load_arrays` (an .npy's array or an .npz's members, read now
    once their declared shapes pass ``check`` and the expansion rule), any decode failure or
    refusal an :class:`InputError` naming the file."""
    try:
        return load_arrays(path, keys, check, expansion)
    except ArrayFileError as exc:
        hint = "" if "numpy" in str(exc) or "not read" in str(exc) else "; write it with numpy.save or numpy.savez"
        raise InputError(f"{exc}{hint}") from None


MAX_CLOUD_POINTS = 30_000_000  # points (rows) a cloud or label file may declare; the generator's clouds stop at 25 M
MAX_TEXT_BYTES = 1 << 30       # a text cloud's size (about 30 M rows of x y z label)


def check_cloud_rows(declared, path: Path) -> None:
    """Refuse, before reading, arrays declaring more than MAX_CLOUD_POINTS rows (``declared``:
    :func:`trajectories.arrays.declared_arrays` of an .npy or .npz)."""
    for name, d in (declared.items() if isinstance(declared, dict) else [("", declared)]):
        if d.rows > MAX_CLOUD_POINTS:
            what = f"member {name!r}" if name else "its array"
            raise InputError(f"{path}: {what} declares {d.rows:,} rows ({d.dtype} {d.shape}); the limit is "
                             f"{MAX_CLOUD_POINTS:,} points: voxel-downsample the cloud first")


MAX_COORDINATE = 1e9  # metres: beyond it a coordinate is refused (squared distances must stay finite)


def regular_file(path: str | Path, what: str = "input") -> Path:
    """``path`` if it names a regular file (symlinks followed); else InputError saying what it is."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path}: is a folder; give the {what} file")
    if not path.exists():
        raise InputError(f"{path}: no such file" + (" (a broken symbolic link)" if path.is_symlink() else ""))
    if not path.is_file():
        raise InputError(f"{path}: not a regular file (a device, pipe or socket); give the {what} file")
    return path


@dataclass
class Cloud:
    """``points`` (N, 3) float64 metres; ``labels`` (N,) int64 label ids or None;
    ``names``: the label table the file states (a PLY ``comment labels [...]``), if any;
    ``dynamic`` (N,) bool: on a moving object (our ground-truth PLY), if known;
    ``observable`` (N,) bool: some camera of the spawn volume can see it (our ground-truth
    PLY from format 0.4), if known."""

    points: np.ndarray
    labels: np.ndarray | None
    source: str
    names: list[str] | None = None
    dynamic: np.ndarray | None = None
    observable: np.ndarray | None = None

    def __post_init__(self):
        """Refuse what cannot be scored exactly: not (N, 3) real numbers, NaN/inf or absurd
        coordinates, labels or flags that are not one integer per point."""
        p = np.asarray(self.points)
        if p.ndim != 2 or p.shape[1] != 3 or p.dtype.kind not in "iuf":
            raise InputError(f"{self.source}: points must be an (N, 3) array of real numbers, got {p.dtype} {p.shape}")
        self.points = p = p.astype(np.float64, copy=False)
        bad = ~np.isfinite(p).all(axis=1)
        if bad.any():
            raise InputError(f"{self.source}: {int(bad.sum())} points have NaN or infinite coordinates "
                             f"(first at row {int(np.argmax(bad))}); remove them")
        if p.size and np.abs(p).max() > MAX_COORDINATE:
            raise InputError(f"{self.source}: a coordinate is {np.abs(p).max():.3g} m from the origin (limit "
                             f"{MAX_COORDINATE:.0e} m); give metres in the ground truth's world frame")
        for name in ("labels", "dynamic", "observable"):
            value = getattr(self, name)
            if value is None:
                continue
            value = np.asarray(value)
            if value.shape != (len(p),):
                raise InputError(f"{self.source}: {len(value) if value.ndim else 'a scalar of'} {name} for "
                                 f"{len(p)} points; give one per point")
            if value.dtype.kind not in ("iu" if name == "labels" else "iub"):
                raise InputError(f"{self.source}: {name} must be integers, got dtype {value.dtype}")
            setattr(self, name, value.astype(np.int64) if name == "labels" else value.astype(bool))

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, keep: np.ndarray) -> "Cloud":
        """The points selected by a boolean mask or index array."""
        pick = (lambda a: None if a is None else a[keep])
        return Cloud(self.points[keep], pick(self.labels), self.source, self.names, pick(self.dynamic),
                     pick(self.observable))


CLOUD_SUFFIXES = (".ply", ".npy", ".npz", ".txt", ".xyz", ".csv", ".pts")


def _text_table(path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    if path.stat().st_size > MAX_TEXT_BYTES:
        raise InputError(f"{path}: a text cloud of {path.stat().st_size:,} bytes, over the limit of "
                         f"{MAX_TEXT_BYTES >> 20:,} MiB; give large clouds as NPY or binary PLY")
    delimiter = "," if path.suffix == ".csv" else None
    try:
        with open(path) as f:
            rows = [ln.replace(",", " ").split() if delimiter else ln.split() for ln in f
                    if ln.strip() and not ln.lstrip().startswith(("#", "//"))]
    except UnicodeDecodeError:
        raise InputError(f"{path}: not a text file; give a PLY, NPY, NPZ or text x y z [label] file") from None
    if not rows:
        raise InputError(f"{path}: empty point cloud")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise InputError(f"{path}: rows have different numbers of columns ({sorted(widths)}); expected x y z [label]")
    width = widths.pop()
    if width not in (3, 4):
        raise InputError(f"{path}: {width} columns; expected (N, 3) x y z or (N, 4) x y z label")
    table = np.array(rows, dtype=object)
    try:
        points = table[:, :3].astype(np.float64)
    except ValueError:
        raise InputError(f"{path}: non-numeric coordinates; expected columns x y z [label]") from None
    labels = table[:, 3].astype(str) if width == 4 else None
    return points, labels


def _split_columns(table: np.ndarray, path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    if table.ndim != 2 or table.shape[1] not in (3, 4):
        shape = "x".join(map(str, table.shape))
        raise InputError(f"{path}: array of shape {shape}; expected (N, 3) x y z or (N, 4) x y z label")
    return table[:, :3], (table[:, 3] if table.shape[1] == 4 else None)


# a cloud file's columns: points, labels, the header's label table, dynamic, observable
Columns = tuple[np.ndarray, np.ndarray | None, list[str] | None, np.ndarray | None, np.ndarray | None]


def _read_ply_cloud(path: Path) -> Columns:
    try:
        d = read_ply(path, max_vertices=MAX_CLOUD_POINTS)
    except PlyError as exc:
        raise InputError(str(exc)) from None
    return _ply_columns(d, path)


def _ply_columns(d: PlyData, path: Path) -> Columns:
    """points, labels, the header's label table, dynamic and observable of a PLY read from ``path``."""
    label = d.vertex.get("label", d.vertex.get("class", d.vertex.get("semantic")))
    names = None
    for c in d.comments:  # our own files name their label table
        if c.startswith("labels "):
            try:
                names = json.loads(c[7:])
            except ValueError:
                raise InputError(f"{path}: its header's label table is not valid JSON; regenerate or fix the file") from None
            if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
                raise InputError(f"{path}: its header's label table is not a list of class names")
    dynamic = d.vertex["dynamic"].astype(bool) if "dynamic" in d.vertex else None
    observable = d.vertex["observable"].astype(bool) if "observable" in d.vertex else None
    return d.points, label, names, dynamic, observable


def read_cloud(path: str | Path, labels_path: str | Path | None = None, label_names: list[str] | None = None) -> Cloud:
    """A point cloud from PLY (ascii or binary; labels from a vertex property ``label``),
    NPY ((N, 3) or (N, 4)), NPZ (arrays ``points`` [+ ``labels``], or a single (N, 3|4) array)
    or text (x y z [label] per line). ``labels_path``: a separate file with one label per
    point (text or NPY); labels may be ids or, with ``label_names``, class names."""
    path = regular_file(path, "point cloud (PLY, NPY, NPZ or text)")
    suffix = path.suffix.lower()
    labels = file_names = dynamic = observable = None
    try:
        if suffix == ".ply":
            points, labels, file_names, dynamic, observable = _read_ply_cloud(path)
        elif suffix == ".npy":
            points, labels = _split_columns(_npy(path), path)
        elif suffix == ".npz":
            points, labels = _npz_columns(load_array_file(path, check=lambda d: check_cloud_rows(d, path)), path)
        elif suffix in CLOUD_SUFFIXES:
            points, labels = _text_table(path)
        else:
            raise InputError(f"{path}: unknown point cloud type {suffix!r}; use one of {', '.join(CLOUD_SUFFIXES)}")
    except (OSError, ValueError, EOFError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{path}: unreadable ({exc.__class__.__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    return _checked_cloud(path, points, labels, file_names, dynamic, observable, labels_path, label_names)


def _npz_columns(arrays, path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """points and labels of an NPZ's members: ``points`` [+ ``labels``], or a single (N, 3|4) array."""
    if not isinstance(arrays, dict):
        raise InputError(f"{path}: an NPY array under an .npz name; rename it .npy")
    if "points" not in arrays:
        if len(arrays) != 1:
            raise InputError(f"{path}: NPZ needs an array 'points' (N, 3) and optionally 'labels' (N,); it has "
                             f"{list(arrays)}")
        return _split_columns(next(iter(arrays.values())), path)
    points, labels = arrays["points"], arrays.get("labels", arrays.get("label"))
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"{path}: 'points' has shape {points.shape}; expected (N, 3)")
    if labels is not None and labels.shape != (len(points),):
        raise InputError(f"{path}: 'labels' has shape {labels.shape} for {len(points)} points; "
                         "give one label per point")
    return points, labels


def ply_cloud(ply: PlyData, path: str | Path) -> Cloud:
    """The :class:`Cloud` of a PLY already read from ``path`` (the ground truth's, read by
    ``exporters.ground_truth.read_points``), checked as :func:`read_cloud` checks a PLY file."""
    path = Path(path)
    return _checked_cloud(path, *_ply_columns(ply, path))


def _checked_cloud(path: Path, points, labels, file_names, dynamic, observable, labels_path=None,
                   label_names=None) -> Cloud:
    """The :class:`Cloud` of columns read from ``path`` (:func:`read_cloud`'s arguments), checked."""
    points = np.asarray(points)
    if points.dtype.kind not in "iuf":
        raise InputError(f"{path}: coordinates are not real numbers (dtype {points.dtype})")
    if len(points) == 0:
        raise InputError(f"{path}: empty point cloud")
    if labels is not None or labels_path is not None:  # labels from the file or from a label file: ids of its table
        _check_file_table(path, file_names, label_names)
    if labels_path is not None:
        if labels is not None:
            raise InputError(f"{path} already has labels; do not pass a separate label file too")
        labels = _read_label_file(Path(labels_path))
        if len(labels) != len(points):
            raise InputError(f"{labels_path}: {len(labels)} labels for {len(points)} points; give one label per point")
    if labels is not None:
        labels = _label_ids(np.asarray(labels), label_names or file_names, path if labels_path is None else Path(labels_path))
    return Cloud(points, labels, str(path), file_names, dynamic, observable)


def _check_file_table(path: Path, file_names: list[str] | None, label_names: list[str] | None) -> None:
    """A label table the file states (a PLY's ``comment labels``) must be the ground truth's."""
    if file_names is None or label_names is None or [n.lower() for n in label_names] == [n.lower() for n in file_names]:
        return  # no table stated, or the same names (case aside)
    raise InputError(f"{path}: its label table {file_names} differs from the ground truth's {label_names}; "
                     "label ids would not match: relabel it with the ground truth's table (labels.json)")


def _npy(path: Path) -> np.ndarray:
    array = load_array_file(path, keys=(), check=lambda d: check_cloud_rows(d, path))  # an NPZ's members are
    # not read: it is refused
    if not isinstance(array, np.ndarray):
        raise InputError(f"{path}: an NPZ archive under an .npy name; rename it .npz")
    return array


def _read_label_file(path: Path) -> np.ndarray:
    path = regular_file(path, "label")
    if path.suffix.lower() == ".npy":
        arr = _npy(path)
        return arr.reshape(-1) if arr.ndim == 2 and 1 in arr.shape else arr
    text = [ln.strip() for ln in path.read_text(errors="replace").splitlines() if ln.strip()]
    return np.array(text)


def _label_ids(labels: np.ndarray, names: list[str] | None, path: Path) -> np.ndarray:
    if labels.ndim != 1:
        raise InputError(f"{path}: labels must be one value per point, got shape {labels.shape}")
    if labels.dtype.kind in "US":
        if _all_numeric(labels):
            return _label_ids(labels.astype(np.float64), names, path)
        return _names_to_ids(labels, names, path)
    if labels.dtype.kind == "f":
        labels = labels.astype(np.float64)  # the range test in float16 would overflow 2 ** 31
        if not np.isfinite(labels).all() or np.any(labels != np.round(labels)) or np.abs(labels).max(initial=0) >= 2 ** 31:
            raise InputError(f"{path}: labels must be integer ids (-1 = unlabelled) or class names")
    if labels.dtype.kind not in "iuf":
        raise InputError(f"{path}: labels must be integer ids or class names (dtype {labels.dtype})")
    if labels.dtype.kind == "u" and labels.size and labels.max() >= 2 ** 31:
        raise InputError(f"{path}: label id {int(labels.max())} is not a class id (-1 = unlabelled, else 0..classes-1)")
    return labels.astype(np.int64)


def _all_numeric(values: np.ndarray) -> bool:
    try:
        v = values.astype(np.float64)
    except ValueError:
        return False
    return bool(np.all(v == np.round(v)))


def _names_to_ids(labels: np.ndarray, names: list[str] | None, path: Path) -> np.ndarray:
    if names is None:
        raise InputError(f"{path}: labels are class names but no label table is known; give integer ids, or score "
                         "against a ground truth whose labels.json names them")
    index = {n.lower(): i for i, n in enumerate(names)}
    out = np.empty(len(labels), np.int64)
    for value in np.unique(labels):
        key = str(value).lower()
        if key not in index:
            raise InputError(f"{path}: unknown class name {str(value)!r}; known: {', '.join(names)}")
        out[labels == value] = index[key]
    return out


def check_label_range(cloud: Cloud, names: list[str], role: str) -> None:
    """Labels must be -1 (unlabelled) or an id of the label table."""
    if cloud.labels is None:
        return
    bad = (cloud.labels < -1) | (cloud.labels >= len(names))
    if bad.any():
        value = int(cloud.labels[np.argmax(bad)])
        raise InputError(f"{cloud.source}: {role} label id {value} is outside the taxonomy (0..{len(names) - 1}, "
                         f"-1 = unlabelled); {int(bad.sum())} points affected")


def read_label_table(path: Path) -> list[str]:
    """labels.json (a JSON list of class names)."""
    try:
        names = json.loads(read_checked_bytes(path))
    except DamagedFileError as exc:
        raise InputError(str(exc)) from None
    except (OSError, ValueError) as exc:
        raise InputError(f"{path}: unreadable label table ({exc.__class__.__name__})") from None
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise InputError(f"{path}: expected a JSON list of class names")
    return names


MAX_SECONDS = 1e7  # timestamps beyond ~115 days are refused (frame numbers must stay exact integers)


def check_poses(poses, source: str) -> np.ndarray:
    """(T, 4, 4) float64 rigid world_from_camera poses: finite, proper rotations (orthonormal,
    det +1: a reflection is not a camera pose), last row 0 0 0 1, positions within
    MAX_COORDINATE metres."""
    p = np.asarray(poses)
    if p.dtype.kind not in "iuf" or p.ndim != 3 or p.shape[1:] != (4, 4):
        raise InputError(f"{source}: poses must be (T, 4, 4) world_from_camera matrices, got {p.dtype} {p.shape}")
    p = p.astype(np.float64)
    if len(p) == 0:
        raise InputError(f"{source}: the trajectory has no poses")
    if not np.isfinite(p).all():
        raise InputError(f"{source}: poses contain NaN or infinite values")
    r = p[:, :3, :3]
    bad = (np.abs(np.einsum("nji,njk->nik", r, r) - np.eye(3)).max(axis=(1, 2)) > 1e-4) | (np.abs(np.linalg.det(r) - 1) > 1e-4)
    bad |= np.any(np.abs(p[:, 3] - [0, 0, 0, 1]) > 1e-9, axis=1)
    if bad.any():
        raise InputError(f"{source}: pose {int(np.argmax(bad))} is not a rigid world_from_camera matrix (rotation "
                         "orthonormal with determinant +1, not a reflection; last row 0 0 0 1)")
    if np.abs(p[:, :3, 3]).max() > MAX_COORDINATE:
        raise InputError(f"{source}: a camera lies {np.abs(p[:, :3, 3]).max():.3g} m from the origin; give metres")
    return p


def check_timestamps(timestamps, count: int, source: str) -> np.ndarray:
    """(T,) float64 seconds: one per pose, finite, within 0..MAX_SECONDS."""
    t = np.asarray(timestamps)
    if t.dtype.kind not in "iuf" or t.shape != (count,):
        raise InputError(f"{source}: {t.shape} timestamps of dtype {t.dtype} for {count} poses; give one number per pose")
    t = t.astype(np.float64)
    if not np.isfinite(t).all():
        raise InputError(f"{source}: timestamps contain NaN or infinite values (pose {int(np.argmax(~np.isfinite(t)))})")
    if count and (t.min() < 0 or t.max() > MAX_SECONDS):
        raise InputError(f"{source}: timestamps must be seconds in 0..{MAX_SECONDS:.0e}, got {t.min():g}..{t.max():g}")
    return t
