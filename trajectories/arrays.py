"""The one reader of the NPY/NPZ files a user gives (trajectories, and every input of
``python -m evaluation``): what a file declares is checked before anything is read.

:func:`declared_arrays` reads only the headers: each array's shape and dtype, and the bytes
it takes in the file. :func:`load_arrays` refuses, before reading any data, a file whose
declarations do not fit the file (an .npy longer or shorter than its header says; an .npz
member whose size in the archive's directory is not its header's), a compressed archive whose
members would expand past ``max(EXPANSION_FLOOR, MAX_EXPANSION x their compressed bytes)``
(so a small file never costs gigabytes), and whatever the caller's ``check`` refuses (its
shape limits), then reads everything at once (no pickles), so that any decode failure is one
:class:`ArrayFileError` naming the file.
"""

from __future__ import annotations

import math
import zipfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# how numpy, zipfile and zlib fail on a damaged .npy/.npz: an empty file raises EOFError, a
# truncated archive zipfile.BadZipFile, a damaged member zlib.error or BadZipFile (CRC), an
# encrypted member or an unknown compression RuntimeError (NotImplementedError), a bad header
# or pickled data ValueError
ARRAY_FILE_ERRORS = (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, RuntimeError)
EXPANSION_FLOOR = 64 << 20  # bytes an archive's members may always declare, however well they compress
MAX_EXPANSION = 32          # beyond the floor: declared bytes per compressed byte (real clouds: 1-4)
NPY_MAGIC, ZIP_MAGICS = b"\x93NUMPY", (b"PK\x03\x04", b"PK\x05\x06")
OTHER_MAGICS = {b"\x89HDF\r\n\x1a\n": "an HDF5 file", b"ply": "a PLY file", b"\x89PNG": "a PNG image",
                b"{": "a JSON file", b"\x80": "a pickle"}


class ArrayFileError(ValueError):
    """An .npy/.npz file that numpy cannot decode, or whose declarations are refused (one
    line: the file and why)."""


@dataclass(frozen=True)
class Declared:
    """What an array's header declares: ``shape``, ``dtype``; ``stored``: the bytes its data
    takes in the file (compressed, for a compressed .npz member)."""

    shape: tuple[int, ...]
    dtype: np.dtype
    stored: int

    @property
    def nbytes(self) -> int:
        return math.prod(self.shape) * self.dtype.itemsize

    @property
    def rows(self) -> int:
        return self.shape[0] if self.shape else 1


def _header(f) -> tuple[tuple[int, ...], np.dtype]:
    version = np.lib.format.read_magic(f)
    read = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}.get(version)
    if read is None:
        raise ValueError(f"NPY format version {version} is not read here")
    shape, _, dtype = read(f, max_header_size=10_000)
    if dtype.hasobject:
        raise ValueError("it holds Python objects (pickled data), not numbers")
    return tuple(int(n) for n in shape), dtype


def _kind(path: Path) -> str:
    """'npy' or 'npz' from the file's first bytes; ArrayFileError naming what else it is."""
    with open(path, "rb") as f:
        head = f.read(8)
    if head.startswith(NPY_MAGIC):
        return "npy"
    if head.startswith(ZIP_MAGICS):
        return "npz"
    what = next((name for magic, name in OTHER_MAGICS.items() if head.startswith(magic)),
                "empty" if not head else "not NumPy's format")
    raise ArrayFileError(f"{path}: not a readable NPY/NPZ file ({what}); write arrays with numpy.save or numpy.savez")


def declared_arrays(path: str | Path, keys: tuple[str, ...] | None = None) -> Declared | dict[str, Declared]:
    """The :class:`Declared` of an .npy's array, or {name: Declared} of an .npz's members (only
    those in ``keys`` when given), read from their headers only; a header that does not fit
    the file raises ArrayFileError."""
    path = Path(path)
    try:
        if _kind(path) == "npy":
            with open(path, "rb") as f:
                shape, dtype = _header(f)
                declared = Declared(shape, dtype, path.stat().st_size - f.tell())
            return _fits(declared, declared.stored, path, "")
        out = {}
        with zipfile.ZipFile(path) as z:
            for info in z.infolist():
                name = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
                if keys is not None and name not in keys:
                    continue
                if not info.filename.endswith(".npy"):
                    raise ArrayFileError(f"{path}: member {name!r} is not a NumPy array (write the file with "
                                         "numpy.savez)")
                with z.open(info) as f:
                    shape, dtype = _header(f)
                    head = f.tell()
                out[name] = _fits(Declared(shape, dtype, info.compress_size), info.file_size - head, path, name)
        return out
    except ArrayFileError:
        raise
    except ARRAY_FILE_ERRORS as exc:
        why = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise ArrayFileError(f"{path}: not a readable NPY/NPZ file ({exc.__class__.__name__}: {why})") from None


def _fits(declared: Declared, data_bytes: int, path: Path, member: str) -> Declared:
    if declared.nbytes != data_bytes:
        where = f"member {member!r}" if member else "its header"
        raise ArrayFileError(f"{path}: {where} declares {declared.dtype} {declared.shape} ({declared.nbytes:,} bytes) "
                             f"but the file holds {max(data_bytes, 0):,}; the file is damaged or not written by numpy")
    return declared


def check_expansion(declared: dict[str, Declared], path: Path) -> None:
    """Refuse members that would expand past max(EXPANSION_FLOOR, MAX_EXPANSION x their stored bytes)."""
    total, stored = sum(d.nbytes for d in declared.values()), sum(d.stored for d in declared.values())
    if total > max(EXPANSION_FLOOR, MAX_EXPANSION * stored):
        raise ArrayFileError(f"{path}: its arrays declare {total:,} bytes compressed into {stored:,} (over "
                             f"{MAX_EXPANSION}x); not read: give the real arrays")


def load_arrays(path: str | Path, keys: tuple[str, ...] | None = None, check=None,
                expansion: bool = True) -> np.ndarray | dict[str, np.ndarray]:
    """The array of an .npy file, or {name: array} of an .npz's members (only those named in
    ``keys`` when given), read now once their declarations pass (module docstring):
    ``check(declared)`` (the :func:`declared_arrays` result) raises to refuse them; with
    ``expansion`` (leave it on unless ``check`` bounds every shape exactly), the
    :func:`check_expansion` rule applies to an .npz's members."""
    declared = declared_arrays(path, keys)
    if check is not None:
        check(declared)
    if expansion and isinstance(declared, dict):
        check_expansion(declared, Path(path))
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):
            return loaded
        with loaded as z:
            arrays = {k: z[k] for k in z.files if keys is None or k in keys}
    except ARRAY_FILE_ERRORS as exc:
        why = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise ArrayFileError(f"{path}: not a readable NPY/NPZ file ({exc.__class__.__name__}: {why})") from None
    for k, v in arrays.items():
        if not isinstance(v, np.ndarray):  # a member not written by numpy.save: numpy returns its bytes
            raise ArrayFileError(f"{path}: member {k!r} is not a NumPy array (write the file with numpy.savez)")
    return arrays
