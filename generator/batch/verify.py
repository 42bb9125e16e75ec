"""``python -m generator verify DIR``: check complete seeds against their manifests (sizes
and sha256 of every file, and no unlisted file). DIR is an output folder or one seed
folder. One line per bad file; exit 0 when everything is intact, 1 when anything is bad,
2 when DIR is neither. bpy-free."""

from __future__ import annotations

import re
import sys
from pathlib import Path

from exporters.manifest import MANIFEST, ManifestError, check_files, load_manifest

from ..cli_args import OneLineParser

SEED_NAME = re.compile(r"seed_\d{6,}")


def seed_problems(folder: Path, hashes: bool = True) -> list[str]:
    """Lines '<folder>/<file>: what is wrong' for one seed folder; empty if intact."""
    if folder.is_symlink() or not folder.is_dir():
        return [f"{folder}: not a folder"]
    try:
        manifest = load_manifest(folder)
    except ManifestError as exc:
        return [str(exc)]
    return [f"{folder / line}" for line in check_files(folder, manifest, hashes)]


def seeds_in(path: Path) -> list[Path]:
    """The seed folders ``path`` names: itself if it holds a manifest, else its seed_* entries."""
    if (path / MANIFEST).exists():
        return [path]
    return sorted(p for p in path.iterdir() if SEED_NAME.fullmatch(p.name))


def main(argv: list[str]) -> int:
    p = OneLineParser(prog="python -m generator verify",
                      description="Check seed folders against their manifests: every listed file present with its "
                                  "size and sha256, no unlisted file. Exit 0: intact; 1: something is bad (one line "
                                  "per bad file); 2: bad input.")
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
        problems = seed_problems(folder, hashes=not args.sizes_only)
        bad += bool(problems)
        for line in problems:
            print(line)
    checked = "sizes" if args.sizes_only else "sizes and sha256"
    print(f"{len(seeds)} seed folder(s) checked ({checked}): {len(seeds) - bad} intact, {bad} bad", file=sys.stderr)
    return 1 if bad else 0
