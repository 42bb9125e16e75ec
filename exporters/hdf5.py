"""HDF5 files that notice their own corruption, and the one way our readers report it.

Every dataset we write carries HDF5's Fletcher-32 checksum filter (so every dataset is
chunked, small ones as a single chunk), and files use the HDF5 1.10 file format, whose
superblock, object headers and chunk indexes carry checksums of their own. Text that must
be protected is stored as fixed-length strings: variable-length strings live in HDF5's
global heap, which has no checksum. A flipped byte in such a file makes h5py fail instead
of returning a different value; :func:`read` turns that failure into one
:class:`DamagedFileError` line naming the file and what to do.

Files written before these checksums (format 0.3 of this week) still read: the checks are
per dataset and simply absent there.
"""

from __future__ import annotations

import errno
import os
from pathlib import Path

import h5py
import numpy as np

LIBVER = ("v110", "v110")  # HDF5 >= 1.10 reads these files (h5py >= 2.10)
CHECKSUM = {"fletcher32": True}
H5_ERRORS = (OSError, KeyError, ValueError, RuntimeError, TypeError)
REMEDY = ("regenerate this seed: rerun python -m generator with its options and --verify --repair "
          "(python -m generator verify DIR lists every damaged file)")


class DamagedFileError(ValueError):
    """A file that is truncated, damaged or not what it should be (one line: which file, what to do)."""


# causes outside the file, for which it cannot be opened or read (errno -> what to do)
ACCESS_ADVICE = {
    errno.EMFILE: "raise this process's open-file limit (ulimit -n) or read fewer seeds at once",
    errno.ENFILE: "the system's open-file table is full; close files elsewhere or raise fs.file-max",
    errno.EACCES: "check the file's permissions",
    errno.EPERM: "check the file's permissions",
    errno.ENOMEM: "free some memory",
}


class AccessError(OSError):
    """A file this process cannot open or read for a cause outside the file (too many open
    files, no permission: :data:`ACCESS_ADVICE`); the file is not damaged. One line: the
    file, the cause, what to do. Made with :func:`access_error`."""

    def __str__(self) -> str:
        return (f"{self.filename}: cannot read it ({self.strerror}; the file itself is not damaged); "
                f"{ACCESS_ADVICE[self.errno]}")


def access_error(exc: BaseException, path: str | Path | None = None) -> AccessError | None:
    """An :class:`AccessError` for ``exc`` (about ``path``, else the file it names) when it is
    an OSError of a cause outside the file, else None: ``raise access_error(exc, path) or damaged(...)``."""
    code = exc.errno if isinstance(exc, OSError) else None
    if code not in ACCESS_ADVICE:
        return None
    return AccessError(code, os.strerror(code), str(path if path is not None else exc.filename))


def damaged(path: str | Path, what: str) -> DamagedFileError:
    """The error for a damaged file: names it, says what failed and what to do."""
    return DamagedFileError(f"{path}: damaged file ({what}); {REMEDY}")


def create_file(path: str | Path) -> h5py.File:
    """A new HDF5 file (truncating ``path``) in the checksummed 1.10 format."""
    return h5py.File(path, "w", libver=LIBVER)


def dataset(group: h5py.Group, name: str, data=None, **kw) -> h5py.Dataset:
    """``group.create_dataset`` with the Fletcher-32 checksum. Arrays without explicit
    ``chunks`` become one chunk; text becomes fixed-length UTF-8 bytes (checksummed)."""
    if data is not None:
        data = np.asarray(data)
        if data.dtype.kind in "OUT" or h5py.check_string_dtype(data.dtype) is not None:
            data = _fixed_text(data)
        if "chunks" not in kw:
            kw["chunks"] = tuple(max(1, n) for n in data.shape) or None
            if 0 in data.shape:
                kw.setdefault("maxshape", (None,) * data.ndim)
    return group.create_dataset(name, data=data, **kw, **CHECKSUM)


def _fixed_text(values: np.ndarray) -> np.ndarray:
    encoded = [v if isinstance(v, bytes) else str(v).encode("utf-8") for v in values.ravel()]
    width = max((len(v) for v in encoded), default=1) or 1
    return np.array(encoded, dtype=f"S{width}").reshape(values.shape)


def text_attribute(value: str) -> np.bytes_:
    """A fixed-length string attribute: it lives in the (checksummed) object header."""
    return np.bytes_(value.encode("utf-8"))


def text(value) -> str:
    """An attribute or dataset element read back as ``str`` (fixed- or variable-length)."""
    if isinstance(value, (bytes, np.bytes_)):
        return bytes(value).decode("utf-8")
    return str(value)


def open_file(path: str | Path) -> h5py.File:
    """Open an HDF5 file for reading; a damaged or foreign file raises :class:`DamagedFileError`,
    one this process cannot open now (too many open files, no permission) :class:`AccessError`."""
    path = Path(path)
    if not path.is_file():
        raise DamagedFileError(f"{path}: no such file; {REMEDY}")
    try:
        return h5py.File(path, "r")
    except H5_ERRORS as exc:
        raise access_error(exc, path) or damaged(path, f"not a readable HDF5 file: {reason(exc)}") from None


def read(node: h5py.Group | h5py.File, key: str, path: str | Path | None = None, sel=()) -> np.ndarray:
    """``node[key][sel]`` as numpy; a missing, damaged or checksum-failing dataset raises
    :class:`DamagedFileError` naming the file and the dataset."""
    path = path if path is not None else node.file.filename
    try:
        return node[key][sel]
    except H5_ERRORS as exc:
        raise damaged(path, f"dataset {_name(node, key)}: {reason(exc)}") from None


def group(node: h5py.Group | h5py.File, key: str, path: str | Path | None = None) -> h5py.Group:
    """``node[key]`` as a group, with the same error as :func:`read`."""
    path = path if path is not None else node.file.filename
    try:
        g = node[key]
    except H5_ERRORS as exc:
        raise damaged(path, f"group {_name(node, key)}: {reason(exc)}") from None
    if not isinstance(g, h5py.Group):
        raise damaged(path, f"{_name(node, key)} is not a group")
    return g


def attribute(node: h5py.Group | h5py.File, key: str, path: str | Path | None = None):
    """``node.attrs[key]``, with the same error as :func:`read`."""
    path = path if path is not None else node.file.filename
    try:
        return node.attrs[key]
    except H5_ERRORS as exc:
        raise damaged(path, f"attribute {_name(node, key)}: {reason(exc)}") from None


def _name(node, key: str) -> str:
    base = getattr(node, "name", "/") or "/"
    return f"{base.rstrip('/')}/{key}"


def reason(exc: BaseException) -> str:
    """The first line of an h5py error, short."""
    message = str(exc).splitlines()[0] if str(exc) else exc.__class__.__name__
    if isinstance(exc, KeyError):
        message = message.strip("'\"")
    return message[:160]


def verify(f: h5py.File, path: str | Path | None = None) -> int:
    """Read every dataset of an open file, chunk by chunk (bounded memory), so that every
    checksum is tested; returns the number of bytes read. A failure raises DamagedFileError."""
    path = path if path is not None else f.filename
    total = 0
    names: list[str] = []
    try:
        f.visititems(lambda name, obj: names.append(name) if isinstance(obj, h5py.Dataset) else None)
    except H5_ERRORS as exc:
        raise damaged(path, f"its index of datasets: {reason(exc)}") from None
    for name in names:
        try:
            ds = f[name]
            if ds.chunks is None or ds.size == 0:
                total += np.asarray(ds[()]).nbytes
                continue
            for sel in ds.iter_chunks():
                total += np.asarray(ds[sel]).nbytes
        except H5_ERRORS as exc:
            raise damaged(path, f"dataset /{name}: {reason(exc)}") from None
    return total
