"""``python -m generator verify DIR``: check complete seeds against their manifests (sizes
and sha256 of every file, no unlisted entry, and a seed folder's name that matches its
manifest's seed). DIR is an output folder or one seed folder (a symlink to one is followed;
a symlink found inside an output folder is reported). One line per bad file; exit 0 when
everything is intact, 1 when anything is bad, 2 when DIR is neither. bpy-free."""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

from exporters.manifest import MANIFEST, ManifestError, check_files, load_manifest

from ..cli_args import OneLineParser
from .folders import seed_folder

SEED_NAME = re.compile(r"seed_\d{6,}")


def seed_problems(folder: Path, hashes: bool = True) -> list[str]:
    """Lines '<folder>/<file>: what is wrong' for one seed folder (a symlink to one is
    followed); empty if intact."""
    if not folder.is_dir():
        return [f"{folder}: not a folder"]
    try:
        manifest = load_manifest(folder)
    except ManifestError as exc:
        return [str(exc)]
    return _misnamed(folder, manifest["seed"]) + [f"{folder / line}" for line in check_files(folder, manifest, hashes)]


def _misnamed(folder: Path, seed: int) -> list[str]:
    """A line when ``folder`` has a seed folder's name but holds another seed."""
    name, right = Path(os.path.abspath(folder)).name, seed_folder(folder.parent, seed).name  # '.' has a name too
    if SEED_NAME.fullmatch(name) and name != right:
        return [f"{folder}: its {MANIFEST} is for seed {seed}, whose folder is named {right}"]
    return []


def entry_problems(entry: Path, hashes: bool = True) -> list[str]:
    """:func:`seed_problems` of a seed folder found inside an output folder, where a symlink
    is not one."""
    return [f"{entry}: a symlink, not a seed folder"] if entry.is_symlink() else seed_problems(entry, hashes)


def seeds_in(path: Path) -> list[Path]:
    """The seed folders ``path`` names: itself if it holds a manifest, else its seed_* entries."""
    if (path / MANIFEST).exists():
        return [path]
    return sorted(p for p in path.iterdir() if SEED_NAME.fullmatch(p.name))


def main(argv: list[str]) -> int:
    p = OneLineParser(prog="python -m generator verify",
                      description="Check seed folders against their manifests: every listed file present with its "
                                  "size and sha256, nothing unlisted, a seed folder's name matching its seed. Exit 0: "
                                  "intact; 1: something is bad (one line per bad file); 2: bad input.")
    p.add_argument("dir", type=Path, help="an output folder (--out of python -m generator) or one seed folder")
    p.add_argument("--sizes-only", action="store_true", help="check sizes, skip hashing (fast, misses same-size changes)")
    args = p.parse_args(argv)
    try:
        if not args.dir.is_dir():
            p.error(f"{args.dir} is not a folder")
        seeds = seeds_in(args.dir)
    except OSError as exc:
        p.error(f"cannot read {args.dir}: {exc.strerror}")
    if not seeds:
        p.error(f"{args.dir} holds no seed folders (seed_NNNNNN) and no {MANIFEST}")
    bad = 0
    for folder in seeds:
        check = seed_problems if folder == args.dir else entry_problems  # DIR itself may be a symlink
        problems = check(folder, hashes=not args.sizes_only)
        bad += bool(problems)
        for line in problems:
            print(line)
    checked = "sizes" if args.sizes_only else "sizes and sha256"
    print(f"{len(seeds)} seed folder(s) checked ({checked}): {len(seeds) - bad} intact, {bad} bad", file=sys.stderr)
    return 1 if bad else 0
