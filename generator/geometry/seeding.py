"""Seeded random streams: one independent ``numpy.random.Generator`` per named subsystem.

A stream is derived from the user's seed and a tuple of names through
``numpy.random.SeedSequence(seed, spawn_key=...)``; names are turned into integers with a
stable hash (sha256), never Python's ``hash`` (which changes with PYTHONHASHSEED).
"""

from __future__ import annotations

import hashlib

import numpy as np

from ..checks import check_seed


def stable_key(name: str | int) -> int:
    """A 32-bit integer from a string (sha256) or an int; identical across processes."""
    if isinstance(name, (int, np.integer)):
        return int(name) & 0xFFFFFFFF
    return int.from_bytes(hashlib.sha256(str(name).encode("utf-8")).digest()[:4], "little")


def stream(seed: int, *names: str | int) -> np.random.Generator:
    """The random stream of subsystem ``names`` for ``seed`` (a non-negative integer)."""
    seed = check_seed("seed", seed)
    key = tuple(stable_key(n) for n in names)
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=key)))
