"""Where the project's tools may write (docs/guarantees.md, "Where the tools write").

One guard for every path a tool writes outside a generated seed (evaluation results, viewer
recordings, baseline outputs, the environment's site cache):

- never inside a generated dataset: a seed folder, a timeline seed, one of its stages, a
  folder being generated (:func:`dataset_containing`): only ``python -m generator`` writes
  there;
- never over a file the tool did not write itself: an existing file is replaced only when it
  carries the project's signature for its kind (:func:`is_ours`; every writer of those kinds
  puts it in, see :data:`KINDS`), so a user's ``paper.json``, photo or recording named as an
  output is refused, while rerunning a tool over its own earlier output works;
- never on a folder, a device, a pipe, an input of the run, or where nothing can be written
  (a real write test, before any work).

Every refusal is one :class:`WriteRefused` line saying what is wrong and what to do.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path

from .manifest import seed_folder_containing

SIGNATURE = "buildee-sites"  # the name every signed output carries (see KINDS)
HEAD_BYTES = 4096  # a signature lies within a file's first bytes: checking one reads no more


class WriteRefused(ValueError):
    """An output location the guard refuses (one line: what is wrong, what to do)."""


def _json_signed(head: bytes) -> bool:  # signed_json puts this key first
    return head.lstrip().startswith(b"{") and f'"written_by": "{SIGNATURE}"'.encode() in head


def _png_signed(head: bytes) -> bool:  # a tEXt chunk "Software" before the image data (png_info)
    return head.startswith(b"\x89PNG\r\n\x1a\n") and b"tEXtSoftware\x00" + SIGNATURE.encode() in head


def _ply_signed(head: bytes) -> bool:  # a header comment (exporters.ply.write_ply)
    return head.startswith(b"ply") and f"comment {PLY_SIGNATURE}".encode() in head


PLY_SIGNATURE = f"written by {SIGNATURE}"  # the first header comment of every PLY (exporters.ply.write_ply)
RRD_APPLICATION_ID = SIGNATURE  # the Rerun application id of every recording (datasets.viewer.common)


def _rrd_signed(head: bytes) -> bool:  # Rerun stores the application id in the stream's first message
    return head.startswith(b"RRF") and RRD_APPLICATION_ID.encode() in head

# kind of output -> test of a file's first HEAD_BYTES bytes: "the project wrote this file"
KINDS = {"json": _json_signed, "png": _png_signed, "ply": _ply_signed, "rrd": _rrd_signed}


def signed_json(results: dict) -> dict:
    """``results`` with the signature as its first key (what :func:`is_ours` looks for)."""
    return {"written_by": SIGNATURE} | {k: v for k, v in results.items() if k != "written_by"}


def png_info():
    """A Pillow ``PngInfo`` carrying the signature; pass it as ``pnginfo=`` to ``Image.save``."""
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    info.add_text("Software", SIGNATURE)
    return info


def is_ours(path: str | Path, kind: str) -> bool:
    """Whether the regular file ``path`` carries the signature of ``kind`` (a key of KINDS)."""
    try:
        with open(path, "rb") as f:
            head = f.read(HEAD_BYTES)
    except OSError:
        return False
    return KINDS[kind](head)


def dataset_containing(path: str | Path) -> Path | None:
    """The generated seed folder (a seed, a timeline seed or a folder being generated) that
    ``path`` is or lies in, if any; a stage ``SEED/phase_K`` lies in its timeline seed. An
    unreadable folder on the way raises WriteRefused."""
    try:
        return seed_folder_containing(path)
    except OSError as exc:
        raise WriteRefused(f"{path}: cannot look at the folders above it ({exc.strerror or exc}); "
                           "choose another place") from None


def check_not_in_dataset(path: str | Path, what: str, shown: str | Path | None = None) -> None:
    """Refuse ``path`` (named ``what`` in the message, e.g. ``--json`` or ``cache_dir``, and
    shown as ``shown``, default ``path``) if it is or lies inside a generated dataset."""
    inside = dataset_containing(path)
    if inside is not None:
        raise WriteRefused(f"{what} {path if shown is None else shown}: lies inside the generated seed folder {inside}, which only "
                           "python -m generator writes; write it elsewhere")


def check_writable_folder(folder: Path, what: str, path: Path) -> None:
    """A real write test in ``folder`` (permissions, read-only or special file systems such as /proc)."""
    if not folder.is_dir():
        raise WriteRefused(f"{what} {path}: its folder does not exist; create it first")
    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=f".{path.name[:64]}.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise WriteRefused(f"{what} {path}: cannot write in {folder} ({exc.strerror or exc}); "
                           "choose a writable folder") from None


def check_output_file(path: str | Path, what: str, kind: str, inputs: tuple = ()) -> None:
    """Refuse, before any work, an output file ``path`` (of ``kind``, a key of KINDS) that is a
    folder or a special file, an input of the run (``inputs``: files, and folders it must stay
    out of), inside a generated dataset, an existing file the project did not write, or in a
    folder where nothing can be written."""
    path = Path(path)
    if kind not in KINDS:
        raise ValueError(f"unknown output kind {kind!r}; one of {sorted(KINDS)}")
    if path.is_dir():
        raise WriteRefused(f"{what} {path}: is a folder; name a file to write")
    if os.path.lexists(path) and (path.is_symlink() or not path.is_file()):
        raise WriteRefused(f"{what} {path}: not a regular file (a link, device, pipe or socket); name a file to write")
    real = Path(os.path.realpath(path))
    check_not_in_dataset(real.parent, what, path)
    for p in inputs:
        p = Path(p)
        if not os.path.exists(p):
            continue
        if p.is_dir():
            if Path(os.path.realpath(p)) in (real, *real.parents):
                raise WriteRefused(f"{what} {path}: lies inside the input folder {p}; write it elsewhere")
        elif path.exists() and path.samefile(p):
            raise WriteRefused(f"{what} {path}: is an input of this run; write the output elsewhere")
    if path.exists() and not is_ours(path, kind):
        raise WriteRefused(f"{what} {path}: exists and was not written by this project (no {SIGNATURE} {kind} "
                           "signature in it); move it away or name a new file")
    check_writable_folder(real.parent, what, path)


FOLDER_MARKER = ".buildee-outputs.json"  # in a folder a tool claimed: which files it wrote, with hashes


class ClaimedFolder:
    """An output folder a tool writes a set of files into (:func:`claim_folder`); :meth:`seal`
    records, when the tool is done, the size and sha256 of every file in it."""

    def __init__(self, folder: Path, tool: str):
        self.folder, self.tool = folder, tool

    def write_marker(self, files: dict, complete: bool) -> None:
        doc = {"written_by": SIGNATURE, "tool": self.tool, "complete": complete, "files": files}
        tmp = self.folder / f"{FOLDER_MARKER}.{os.getpid()}.tmp"
        try:
            tmp.write_text(json.dumps(doc, indent=1, sort_keys=True))
            os.replace(tmp, self.folder / FOLDER_MARKER)
        finally:
            tmp.unlink(missing_ok=True)

    def seal(self) -> None:
        """Record every file now in the folder as the tool's (call when the tool is done)."""
        self.write_marker({rel: _stamp(self.folder / rel) for rel in _files(self.folder)}, True)


def _files(folder: Path) -> list[str]:
    """Every entry under ``folder`` but the marker, as relative POSIX paths (folders left out;
    a symlink or a special file is listed, so that it is refused)."""
    out = []
    for root, dirs, names in os.walk(folder):
        base = Path(root)
        for p in [base / n for n in dirs if (base / n).is_symlink()] + [base / n for n in names]:
            rel = p.relative_to(folder).as_posix()
            if rel != FOLDER_MARKER and not (rel.startswith(FOLDER_MARKER) and rel.endswith(".tmp")):
                out.append(rel)
    return sorted(out)


def _stamp(path: Path) -> dict | None:
    """{bytes, sha256} of a regular file; None for anything else (a link, a FIFO)."""
    if path.is_symlink() or not path.is_file():
        return None
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(1 << 20):
            h.update(block)
    return {"bytes": path.stat().st_size, "sha256": h.hexdigest()}


def _read_marker(folder: Path) -> dict | None:
    try:
        doc = json.loads((folder / FOLDER_MARKER).read_bytes())
    except (OSError, ValueError, RecursionError):
        return None
    ok = isinstance(doc, dict) and doc.get("written_by") == SIGNATURE and isinstance(doc.get("files"), dict)
    return doc if ok else None


def claim_folder(folder: str | Path, what: str, tool: str) -> ClaimedFolder:
    """Check and claim the output folder ``folder`` (``what``: its flag) for ``tool``, before any
    work: not inside a generated dataset; new (created here), empty, or claimed by ``tool``
    before, holding only files that tool wrote, unchanged since (sizes and sha256 in its
    marker; after a run that did not finish, the files it left are taken as the tool's)."""
    folder = Path(folder)
    check_not_in_dataset(folder, what)
    if os.path.lexists(folder) and not folder.is_dir():
        raise WriteRefused(f"{what} {folder}: exists and is not a folder; name a folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise WriteRefused(f"{what} {folder}: cannot create it ({exc.strerror or exc}); choose another folder") from None
    files, marker = _files(folder), _read_marker(folder)
    if files and marker is None:
        raise WriteRefused(f"{what} {folder}: holds files this project did not write ({files[0]}, ...); "
                           "choose a new or empty folder")
    if marker is not None and marker.get("tool") != tool:
        raise WriteRefused(f"{what} {folder}: holds the outputs of {marker.get('tool')!r}; choose another folder")
    if marker is not None and marker.get("complete"):
        for rel in files:
            if marker["files"].get(rel) is None or _stamp(folder / rel) != marker["files"][rel]:
                raise WriteRefused(f"{what} {folder}: {rel} was not written by {tool} or changed since; "
                                   "move it away or choose another folder")
    claimed = ClaimedFolder(folder, tool)
    check_writable_folder(folder, what, folder / FOLDER_MARKER)
    claimed.write_marker(marker["files"] if marker else {}, False)
    return claimed
