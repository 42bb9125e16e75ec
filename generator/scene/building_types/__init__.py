"""Building types (bpy-free): how a building under construction is built, one entry each.

A :class:`BuildingType` names a structure and its construction sequence: its builder
``build(rng, phase, floors, max_length, growth) -> Asset`` (the asset in its own frame,
centred on the origin, as :mod:`generator.scene.catalogue.buildings` places it), its share
of the buildings drawn (``weight``) and the materials only it uses. Every module of this
package declares its types next to their builders and registers them with
:func:`register_type`; :func:`all_types` imports the package's modules (sorted by name) the
first time it is asked, so a new type is one new file here and no other edit. The Building
kind draws one type per building (:func:`choose_type`) and grows it over a timeline's stages
through :class:`Growth` (docs/scenes.md, "Building types")."""

from __future__ import annotations

import importlib
import pkgutil
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..materials import Material

SCANNED = True  # every module of this package is loaded by name (generator/envs/code_key.py reads them all)


@dataclass(frozen=True)
class Growth:
    """A later stage of a building (docs/phases.md): ``built`` levels of structure and
    ``enclosed`` levels of envelope (from the ground up), at least the building's own at
    stage 0. ``floor_rng(k)`` gives the random stream of envelope level ``k`` for levels
    beyond those the building drew itself, so the draws of every other part stay as at
    stage 0."""

    built: int
    enclosed: int
    floor_rng: Callable[[int], np.random.Generator]

    def check(self, own_built: int, planned: int) -> None:
        """ValueError unless ``own_built`` <= built <= ``planned`` and built - 2 (at least
        own_built - 2) <= enclosed <= built."""
        if not own_built <= self.built <= planned or not max(0, own_built - 2) <= self.enclosed <= self.built:
            raise ValueError(f"building growth {self.built} levels built, {self.enclosed} enclosed is outside "
                             f"[{own_built}, {planned}] built and [{max(0, own_built - 2)}, built] enclosed")


@dataclass(frozen=True)
class BuildingType:
    """One type of building under construction.

    - ``name``: the type (site.json's ``buildings[i].type``, ``--building-type``).
    - ``build``: ``build(rng, phase, floors, max_length, growth) -> Asset``: ``phase`` the
      share of the planned levels built at stage 0 (at least one), ``floors`` (fewest, most)
      planned levels, ``max_length`` metres the footprint (temporary works included) stays
      within, ``growth`` None at stage 0 or a :class:`Growth`. The asset's ``info`` holds
      ``floors_built``, ``floors_planned``, ``floors_enclosed``, ``height`` (metres, the top
      of its ``Building`` part: the structure and what runs ahead of it, e.g. a core) and
      ``floor_height``.
    - ``weight``: its share of the buildings drawn per seed (relative to the other types').
    - ``structure``: what it is made of and how it goes up, in words (docs/scenes.md).
    - ``materials``: the :class:`~generator.scene.materials.Material` s only it uses.
    """

    name: str
    build: Callable[..., object]
    weight: float
    structure: str
    materials: tuple[Material, ...] = ()
    module: str = ""


_TYPES: dict[str, BuildingType] = {}
_scanned = False


def register_type(entry: BuildingType) -> BuildingType:
    """Add ``entry`` (at module level of a module of this package); a name registered twice
    or a weight that is not positive is a ValueError."""
    if entry.name in _TYPES:
        raise ValueError(f"building type {entry.name!r} is registered twice ({_TYPES[entry.name].module} and "
                         f"{entry.module}); give the new type another name")
    if not entry.weight > 0:
        raise ValueError(f"building type {entry.name!r}: weight must be positive, got {entry.weight!r}")
    _TYPES[entry.name] = entry
    return entry


def _scan() -> None:
    global _scanned
    if _scanned:
        return
    _scanned = True
    try:
        for name in sorted(m.name for m in pkgutil.iter_modules(__path__)):
            importlib.import_module(f"{__name__}.{name}")
    except BaseException:
        _scanned = False
        raise


def all_types() -> list[BuildingType]:
    """Every registered type, sorted by name."""
    _scan()
    return [_TYPES[name] for name in sorted(_TYPES)]


def building_type(name: str) -> BuildingType:
    """The entry of type ``name``; ValueError naming the known types if there is none."""
    _scan()
    if name not in _TYPES:
        raise ValueError(f"unknown building type {name!r}; choose one of {', '.join(sorted(_TYPES))}")
    return _TYPES[name]


def check_building_type(name: str | None) -> None:
    """ValueError unless ``name`` is None (drawn per building) or a registered type."""
    if name is not None:
        building_type(name)


def choose_type(rng: np.random.Generator) -> BuildingType:
    """One type drawn by weight from ``rng`` (one uniform draw)."""
    types = all_types()
    weights = np.array([t.weight for t in types], dtype=float)
    edges = np.cumsum(weights / weights.sum())
    return types[min(int(np.searchsorted(edges, rng.random(), side="right")), len(types) - 1)]


def type_materials() -> tuple[Material, ...]:
    """Every type's own materials (types sorted by name)."""
    return tuple(m for t in all_types() for m in t.materials)
