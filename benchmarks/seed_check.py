"""What checking a complete seed against its manifest costs, side by side with
``openssl dgst -sha256`` over the same files (the strongest honest reference for hashing files:
OpenSSL's SHA-256 uses the CPU's SHA instructions where it has them; coreutils' ``sha256sum``,
the reference until 2026-11-23, does not, and is about 4x slower here).

    python benchmarks/seed_check.py SEED_FOLDER [--copies N]

With --copies N the seed's files are copied N times into one temporary folder (with its own
manifest) to reach the size of a default seed (~330 MB) from a tiny one; hashing speed does
not depend on what the bytes are. Times are with the files in the page cache (each set is
read once before timing); a first read from disk adds the disk's read time, measured here
with O_DIRECT reads, which bypass the cache without evicting anything."""

from __future__ import annotations

import argparse
import mmap
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from exporters.manifest import check_files, load_manifest, write_manifest  # noqa: E402


def _best(fn, repeat: int = 3) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def _read_uncached(path: Path, block: int = 4 << 20) -> None:
    """Read a file with O_DIRECT (from the disk, around the page cache)."""
    buf = mmap.mmap(-1, block)  # page-aligned, as O_DIRECT requires
    fd = os.open(path, os.O_RDONLY | os.O_DIRECT)
    try:
        while os.readv(fd, [buf]) == block:
            pass
    finally:
        os.close(fd)
        buf.close()


def _replicated(seed: Path, copies: int, into: Path) -> Path:
    folder = into / seed.name
    for k in range(copies):
        shutil.copytree(seed, folder / f"copy{k}", ignore=shutil.ignore_patterns("manifest.json"))
    write_manifest(folder, {"format_version": "bench", "seed": 0, "config": {}})
    return folder


def _run_parallel(commands: list[list[str]]) -> None:
    procs = [subprocess.Popen(c, stdout=subprocess.DEVNULL) for c in commands]
    if any(p.wait() for p in procs):
        raise RuntimeError("a reference process failed")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("seed", type=Path)
    p.add_argument("--copies", type=int, default=1)
    args = p.parse_args()
    with tempfile.TemporaryDirectory(dir="/tmp") as tmp:
        folder = _replicated(args.seed, args.copies, Path(tmp)) if args.copies > 1 else args.seed
        manifest = load_manifest(folder)
        files = [folder / rel for rel in manifest["files"]]
        size = sum(f.stat().st_size for f in files)
        subprocess.run(["cat", *map(str, files)], stdout=subprocess.DEVNULL, check=True)  # warm the cache
        sizes = _best(lambda: check_files(folder, manifest, hashes=False))
        quick = _best(lambda: check_files(folder, manifest, hashes=None))
        ours = _best(lambda: check_files(folder, manifest, hashes=True))
        ref = _best(lambda: subprocess.run(["openssl", "dgst", "-sha256", *map(str, files)], stdout=subprocess.DEVNULL,
                                           check=True))
        cores = os.cpu_count() or 1
        chunk = max(1, -(-len(files) // cores))
        parallel = _best(lambda: _run_parallel([["openssl", "dgst", "-sha256", *map(str, files[i:i + chunk])]
                                                for i in range(0, len(files), chunk)]))
        coreutils = _best(lambda: subprocess.run(["sha256sum", *map(str, files)], stdout=subprocess.DEVNULL, check=True))
        t = time.perf_counter()
        for f in files:
            _read_uncached(f)
        disk = time.perf_counter() - t
    mb = size / 1e6
    print(f"{len(files)} files, {mb:.0f} MB")
    print(f"sizes only (default rerun, files untouched): {sizes * 1e3:.1f} ms")
    print(f"sizes + hash of files whose mtime changed (none): {quick * 1e3:.1f} ms")
    print(f"sha256 of every file (--verify, verify): {ours:.2f} s = {mb / ours:.0f} MB/s")
    print(f"openssl dgst -sha256 over the same files (reference): {ref:.2f} s = {mb / ref:.0f} MB/s; "
          f"ratio ours/openssl {ours / ref:.2f}")
    print(f"openssl dgst -sha256 on every core ({cores} processes, files split evenly): {parallel:.2f} s = "
          f"{mb / parallel:.0f} MB/s; ratio ours/parallel openssl {ours / parallel:.2f}")
    print(f"sha256sum (coreutils, no SHA instructions) over the same files: {coreutils:.2f} s = {mb / coreutils:.0f} MB/s")
    print(f"reading them from disk (O_DIRECT, uncached): {disk:.2f} s = {mb / disk:.0f} MB/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
