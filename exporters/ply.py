"""PLY files: point clouds and triangle meshes with extra per-vertex and per-face properties.

Written binary little-endian (open3d, MeshLab, CloudCompare read them); read back from
binary (either byte order) and ASCII files. Faces are triangles stored as a
``vertex_indices`` list with a ``uchar`` count. Every problem with a file raises
:class:`PlyError` with a one-line message.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .write_guard import PLY_SIGNATURE

_TYPES = {  # PLY type name -> numpy type code (without byte order)
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
    "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}
_NAMES = {"i1": "char", "u1": "uchar", "i2": "short", "u2": "ushort", "i4": "int", "u4": "uint", "f4": "float", "f8": "double"}


class PlyError(ValueError):
    """A PLY file that cannot be read (the message says why)."""


@dataclass
class PlyData:
    """``vertex``: property name -> (N,) array; ``faces`` (F, 3) int64 or None;
    ``face``: extra face property name -> (F,) array; ``comments``: header comments."""

    vertex: dict[str, np.ndarray]
    faces: np.ndarray | None = None
    face: dict[str, np.ndarray] = field(default_factory=dict)
    comments: list[str] = field(default_factory=list)

    @property
    def points(self) -> np.ndarray:
        """(N, 3) float64 x, y, z."""
        return np.stack([self.vertex[c].astype(np.float64) for c in "xyz"], axis=1)


def _type_name(array: np.ndarray) -> str:
    code = np.asarray(array).dtype.str[1:]
    if code == "b1":
        return "uchar"
    if code not in _NAMES:
        raise TypeError(f"PLY cannot store dtype {np.asarray(array).dtype}")
    return _NAMES[code]


def write_ply(path: str | Path, vertex: dict[str, np.ndarray], faces: np.ndarray | None = None,
              face: dict[str, np.ndarray] | None = None, comments: list[str] | tuple[str, ...] = ()) -> Path:
    """Write a binary little-endian PLY. ``vertex`` maps property names to (N,) arrays (their
    dtypes are kept; put x, y, z first); ``faces`` (F, 3) vertex indices; ``face`` extra
    (F,) face properties. The first comment is the project's signature (exporters.write_guard)."""
    path = Path(path)
    names = list(vertex)
    n = len(vertex[names[0]]) if names else 0
    if any(len(np.asarray(v)) != n for v in vertex.values()):
        raise ValueError("all vertex properties must have the same length")
    header = ["ply", "format binary_little_endian 1.0", f"comment {PLY_SIGNATURE}", *(f"comment {c}" for c in comments),
              f"element vertex {n}"]
    header += [f"property {_type_name(vertex[k])} {k}" for k in names]
    vdtype = np.dtype([(k, "<" + np.dtype(_TYPES[_type_name(vertex[k])]).str[1:]) for k in names])
    vrec = np.empty(n, dtype=vdtype)
    for k in names:
        vrec[k] = vertex[k]
    frec = None
    if faces is not None:
        faces = np.asarray(faces)
        face = face or {}
        header += [f"element face {len(faces)}", "property list uchar int vertex_indices"]
        header += [f"property {_type_name(face[k])} {k}" for k in face]
        fdtype = np.dtype([("n", "u1"), ("idx", "<i4", (3,))] + [(k, "<" + np.dtype(_TYPES[_type_name(face[k])]).str[1:]) for k in face])
        frec = np.empty(len(faces), dtype=fdtype)
        frec["n"], frec["idx"] = 3, faces
        for k in face:
            frec[k] = face[k]
    header.append("end_header")
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")  # never a half-written file under the real name
    try:
        with open(tmp, "wb") as f:
            f.write(("\n".join(header) + "\n").encode("ascii"))
            f.write(vrec.tobytes())
            if frec is not None:
                f.write(frec.tobytes())
        tmp.replace(path)
    finally:  # nothing left behind when the write or the rename fails
        tmp.unlink(missing_ok=True)
    return path


@dataclass
class _Element:
    name: str
    count: int
    props: list[tuple[str, str, str | None]]  # (name, type code, list count type code or None)


_MAX_HEADER_LINE = 1 << 20  # bytes; a longer header line (or a header past _MAX_HEADER) is refused
_MAX_HEADER = 16 << 20


def _parse_header(f, path: Path) -> tuple[str, list[_Element], list[str]]:
    if f.readline(16).strip() != b"ply":
        raise PlyError(f"{path}: not a PLY file (it does not start with 'ply')")
    fmt, elements, comments = None, [], []
    while True:
        line = f.readline(_MAX_HEADER_LINE + 1)
        if not line:
            raise PlyError(f"{path}: truncated PLY header (no end_header)")
        if len(line) > _MAX_HEADER_LINE or f.tell() > _MAX_HEADER:
            raise PlyError(f"{path}: PLY header line or header longer than {_MAX_HEADER_LINE >> 20} MiB; not a point cloud we read")
        words = line.decode("ascii", errors="replace").split()
        if not words or words[0] in ("obj_info",):
            continue
        if words[0] == "end_header":
            break
        try:
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "comment":
                comments.append(line.decode("ascii", errors="replace").strip()[8:])
            elif words[0] == "element":
                _unique(words[1] in [e.name for e in elements], f"element {words[1]!r}", path)
                elements.append(_Element(words[1], int(words[2]), []))
                if elements[-1].count < 0:
                    raise PlyError(f"{path}: element {words[1]!r} has a negative count ({words[2]})")
            elif words[0] == "property":
                listed = words[1] == "list"
                prop = (words[4], _TYPES[words[3]], _TYPES[words[2]]) if listed else (words[2], _TYPES[words[1]], None)
                _unique(prop[0] in [p[0] for p in elements[-1].props],
                        f"property {prop[0]!r} of element {elements[-1].name!r}", path)
                elements[-1].props.append(prop)
            else:
                raise PlyError(f"{path}: unexpected PLY header line {line.strip()[:80]!r}")
        except (IndexError, KeyError, ValueError) as exc:
            if isinstance(exc, PlyError):
                raise
            raise PlyError(f"{path}: bad PLY header line {line.strip()[:80]!r}") from exc
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise PlyError(f"{path}: unknown PLY format {fmt!r}")
    return fmt, elements, comments


def _unique(twice: bool, what: str, path: Path) -> None:
    """Refuse a header naming an element, or a property of one element, twice (which would be meant?)."""
    if twice:
        raise PlyError(f"{path}: the PLY header names {what} twice; give each a name of its own")


def read_ply_comments(path: str | Path) -> list[str]:
    """The header comments of a PLY file (the header only is read)."""
    path = Path(path)
    if not path.is_file():
        raise PlyError(f"{path}: no such file")
    with open(path, "rb") as f:
        return _parse_header(f, path)[2]


def read_ply(path: str | Path, max_vertices: int | None = None) -> PlyData:
    """Read a PLY point cloud or triangle mesh (ASCII or binary). Polygons with more than
    three corners are split into triangle fans; face properties repeat for each triangle.
    The element counts the header declares must describe the whole file: a binary body of
    another length than they imply (checked before it is read, when every row has a fixed
    size) or rows left over after the last element are refused, as is a header declaring
    more than ``max_vertices`` vertices."""
    path = Path(path)
    if not path.is_file():
        raise PlyError(f"{path}: no such file")
    with open(path, "rb") as f:
        fmt, elements, comments = _parse_header(f, path)
        _check_declared(elements, fmt, path.stat().st_size - f.tell(), max_vertices, path)
        body = f.read()
    data: dict[str, dict[str, np.ndarray]] = {}
    if fmt == "ascii":
        end, total = _read_ascii(body, elements, data, path)
        unit = "rows"
    else:
        end = _read_binary(body, elements, data, "<" if fmt == "binary_little_endian" else ">", path)
        total, unit = len(body), "bytes"
    if end != total:
        raise PlyError(f"{path}: {total - end} {unit} after the last element the header declares; the header's "
                       "element counts do not match the file: fix them or rewrite the file")
    if "vertex" not in data:
        raise PlyError(f"{path}: no vertex element")
    vertex = data["vertex"]
    if not all(c in vertex for c in "xyz"):
        raise PlyError(f"{path}: vertices need x, y and z properties")
    if not all(isinstance(vertex[c], np.ndarray) and vertex[c].ndim == 1 for c in "xyz"):
        raise PlyError(f"{path}: vertex x, y and z must be single numbers, not lists")
    faces, face = None, {}
    if "face" in data:
        face = data["face"]
        lists = face.pop("vertex_indices", face.pop("vertex_index", None))
        if lists is not None:
            faces, repeat = _triangulate(lists, path)
            face = {k: np.repeat(v, repeat) for k, v in face.items()}
            if len(faces) and (faces.min() < 0 or faces.max() >= len(vertex["x"])):
                raise PlyError(f"{path}: a face refers to a vertex that does not exist")
    return PlyData(vertex, faces, face, comments)


def _check_declared(elements: list[_Element], fmt: str, body_bytes: int, max_vertices: int | None, path: Path) -> None:
    """Refuse, before the body is read, a vertex count over ``max_vertices`` and a binary body
    whose length differs from what fixed-size rows of the declared counts take."""
    vertices = next((e.count for e in elements if e.name == "vertex"), 0)
    if max_vertices is not None and vertices > max_vertices:
        raise PlyError(f"{path}: declares {vertices:,} vertices, over the limit of {max_vertices:,}; "
                       "voxel-downsample the cloud first")
    if fmt == "ascii" or any(c is not None for e in elements for _, _, c in e.props):
        return  # ASCII rows and list properties have no fixed size: checked after reading
    need = sum(e.count * sum(np.dtype(code).itemsize for _, code, _ in e.props) for e in elements)
    if need != body_bytes:
        what = "truncated PLY data" if need > body_bytes else "more data than its header declares"
        raise PlyError(f"{path}: {what}: the header's element counts need {need:,} bytes, the file holds "
                       f"{body_bytes:,} after its header; fix the counts or rewrite the file")


def _triangulate(lists, path: Path) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(lists, np.ndarray) and lists.ndim == 2:
        if lists.shape[1] < 3:
            raise PlyError(f"{path}: faces need at least 3 vertices")
        k = lists.shape[1]
        fans = [lists[:, [0, j, j + 1]] for j in range(1, k - 1)]
        return np.stack(fans, axis=1).reshape(-1, 3).astype(np.int64), np.full(len(lists), k - 2)
    tris, repeat = [], []
    for poly in lists:
        if len(poly) < 3:
            raise PlyError(f"{path}: faces need at least 3 vertices")
        tris.extend((poly[0], poly[j], poly[j + 1]) for j in range(1, len(poly) - 1))
        repeat.append(len(poly) - 2)
    return np.asarray(tris, dtype=np.int64).reshape(-1, 3), np.asarray(repeat, dtype=np.int64)


def _read_binary(body: bytes, elements: list[_Element], data: dict, order: str, path: Path) -> int:
    """Read ``elements`` from ``body`` into ``data``; returns the bytes they took."""
    pos = 0
    for el in elements:
        lists = [(name, count_code) for name, _, count_code in el.props if count_code is not None]
        if len(lists) == 1 and el.count:
            # fast path: every row's list as long as the first row's (true for triangle meshes)
            name, count_code = lists[0]
            head = sum(np.dtype(code).itemsize for n, code, _ in el.props[:[p[0] for p in el.props].index(name)])
            if pos + head + np.dtype(count_code).itemsize > len(body):
                raise PlyError(f"{path}: truncated PLY data in element {el.name!r}")
            k = int(np.frombuffer(body, dtype=order + count_code, count=1, offset=pos + head)[0])
            fields = []
            for n, code, c in el.props:
                fields += [(n, order + code)] if c is None else [(n + "#n", order + c), (n, order + code, (k,))]
            dtype = np.dtype(fields)
            end = pos + dtype.itemsize * el.count
            if end <= len(body):
                rec = np.frombuffer(body, dtype=dtype, count=el.count, offset=pos)
                if np.all(rec[name + "#n"] == k):
                    data[el.name] = {n: np.array(rec[n]) for n, _, _ in el.props}
                    pos = end
                    continue
        if lists:
            pos = _read_binary_lists(body, el, data, order, pos, path)
            continue
        dtype = np.dtype([(name, order + code) for name, code, _ in el.props])
        end = pos + dtype.itemsize * el.count
        if end > len(body):
            raise PlyError(f"{path}: truncated PLY data: element {el.name!r} needs {end - pos} bytes, "
                           f"{max(len(body) - pos, 0)} left")
        rec = np.frombuffer(body, dtype=dtype, count=el.count, offset=pos)
        data[el.name] = {n: np.array(rec[n]).astype(rec[n].dtype.newbyteorder("=")) for n, _, _ in el.props}
        pos = end
    return pos


def _read_binary_lists(body: bytes, el: _Element, data: dict, order: str, pos: int, path: Path) -> int:
    """Slow path: lists of varying length, row by row."""
    out = {n: [] for n, _, _ in el.props}
    try:
        for _ in range(el.count):
            for name, code, count_code in el.props:
                if count_code is None:
                    v = np.frombuffer(body, dtype=order + code, count=1, offset=pos)[0]
                    pos += np.dtype(code).itemsize
                else:
                    k = int(np.frombuffer(body, dtype=order + count_code, count=1, offset=pos)[0])
                    pos += np.dtype(count_code).itemsize
                    v = np.frombuffer(body, dtype=order + code, count=k, offset=pos).astype(np.int64)
                    pos += k * np.dtype(code).itemsize
                out[name].append(v)
    except ValueError as exc:
        raise PlyError(f"{path}: truncated PLY data in element {el.name!r}") from exc
    data[el.name] = {n: (v if c is not None else np.array(v)) for (n, _, c), v in zip(el.props, out.values())}
    return pos


def _read_ascii(body: bytes, elements: list[_Element], data: dict, path: Path) -> tuple[int, int]:
    """Read ``elements`` from ``body`` into ``data``; returns (rows they took, non-empty rows there are)."""
    lines = body.decode("ascii", errors="replace").splitlines()
    lines = [ln for ln in lines if ln.strip()]
    pos = 0
    for el in elements:
        rows = lines[pos:pos + el.count]
        if len(rows) < el.count:
            raise PlyError(f"{path}: truncated PLY data: element {el.name!r} has {len(rows)} of {el.count} rows")
        pos += el.count
        fixed = all(c is None for _, _, c in el.props)
        try:
            if fixed:
                table = np.array([r.split() for r in rows], dtype=np.float64).reshape(el.count, -1) if el.count else np.zeros((0, len(el.props)))
                if table.shape[1] != len(el.props):
                    raise PlyError(f"{path}: element {el.name!r} rows have {table.shape[1]} values, expected {len(el.props)}")
                data[el.name] = {n: _ascii_values(table[:, j], code, n, el.name, path)
                                 for j, (n, code, _) in enumerate(el.props)}
                continue
            out = {n: [] for n, _, _ in el.props}
            for r in rows:
                words, j = r.split(), 0
                for name, code, count_code in el.props:
                    if count_code is None:
                        out[name].append(float(words[j]))
                        j += 1
                    else:
                        k = int(words[j])
                        out[name].append(np.array(words[j + 1:j + 1 + k], dtype=np.int64))
                        j += 1 + k
            data[el.name] = {n: (v if c is not None else _ascii_values(np.array(v, np.float64), code, n, el.name, path))
                             for (n, code, c), v in zip(el.props, out.values())}
        except (ValueError, IndexError) as exc:
            if isinstance(exc, PlyError):
                raise
            raise PlyError(f"{path}: malformed ASCII PLY row in element {el.name!r}") from exc
    return pos, len(lines)


def _ascii_values(values: np.ndarray, code: str, name: str, element: str, path: Path) -> np.ndarray:
    """float64 ``values`` of an ASCII property as its type ``code``; PlyError for a value the
    type cannot hold (an integer type: a fraction, NaN or a value out of its range; float: beyond float32's)."""
    dtype = np.dtype(code)
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        bad = ~((values == np.round(values)) & (values >= info.min) & (values <= info.max))
    else:
        bad = np.isfinite(values) & (np.abs(values) > np.finfo(dtype).max)
    if bad.any():
        row = int(np.argmax(bad))
        raise PlyError(f"{path}: element {element!r} property {name!r} holds {float(values[row])!r} (row {row}), "
                       f"which type {_NAMES[code]} cannot hold; fix the value or the property's declared type")
    return values.astype(dtype)
