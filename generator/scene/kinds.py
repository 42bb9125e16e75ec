"""The asset catalogue: one :class:`AssetKind` entry per kind of site object (bpy-free).

Each module of the package :mod:`generator.scene.catalogue` declares its kinds next to
their builders and registers them with :func:`register`; :func:`all_kinds` imports every
module of that package (``pkgutil``, sorted by module name) the first time it is asked, so a
new kind is one new file there and no other edit. Everything that treats kinds differently
reads the entries: the site plan (:mod:`.site`, each entry's ``place`` and ``order``), the
presets (``counts``), the taxonomy (``classes``, ``colour``), the timeline (``stage``) and
the materials (``materials``, :mod:`generator.blender.materials`). See docs/scenes.md,
"The asset catalogue".
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping

from .materials import SHARED, Material

CATALOGUE = __name__.rsplit(".", 1)[0] + ".catalogue"  # the package whose modules declare the kinds
FIRST_NEW_ORDER = 1000  # default ``order`` of a new kind: planned after every kind of the first release


@dataclass(frozen=True)
class AssetKind:
    """One kind of site object.

    - ``name``: the kind (``Asset.kind``; names its random streams, its Blender collection
      and its count in site.json), unique in the catalogue.
    - ``classes``: the taxonomy classes its parts are labelled with, its own first (a
      building's parts are Building, Rebar, Formwork and Scaffolding). A class missing from
      the fixed taxonomy is a new class, appended (:mod:`.taxonomy`); it needs ``colour``.
    - ``build``: the builder, ``build(rng, ...) -> Asset`` in the asset's own frame (its
      placement rule says what else it is given: a kind that moves also gets the
      animation's ``frames`` and ``fps``).
    - ``place``: how the plan places it (a placement rule of :mod:`.planning`, or None
      for what the site adds itself: the ground). ``order``: when, among all kinds.
    - ``counts``: per preset name, (fewest, most) of this kind on a site; presets it does not
      name have none. ``count_param``: the :class:`~.site.SiteParams` field that holds
      them (the first release's buildings, trucks, excavators); None: ``SiteParams.counts``.
    - ``materials``: the :class:`~.materials.Material` s only this kind uses.
    - ``motion``: how it moves, in words ('' if it never does).
    - ``stage``: how it changes between the stages of a timeline (a rule of
      :mod:`.timeline`; None: it stays as it is).
    - ``colour``: RGB 0-255 of a new class in maps and figures.
    - ``scenery``: it stands beyond the fence as scenery (the surroundings): rendered and in
      every per-pixel ground truth, but without surface or scoring points (the point clouds
      cover the site; :class:`generator.geometry.parts.MeshPart` ``scenery``).
    - ``shared_streams``: True only for the kinds of the first release, whose counts, prop
      mix and per-stage draws come from the site's shared streams in ``order`` (which is
      why their order is fixed); a new kind leaves it False and draws only from streams
      named after itself, so adding it shifts no other kind's draws.
    """

    name: str
    classes: tuple[str, ...]
    build: Callable[..., Any] | None
    place: Any = None
    order: int = FIRST_NEW_ORDER
    counts: Mapping[str, tuple[int, int]] = field(default_factory=dict)
    count_param: str | None = None
    materials: tuple[Material, ...] = ()
    motion: str = ""
    stage: Any = None
    colour: tuple[int, int, int] | None = None
    shared_streams: bool = False
    scenery: bool = False
    module: str = ""  # the module that registered it (set by :func:`register`)

    @property
    def label(self) -> str:
        """The kind's own taxonomy class."""
        return self.classes[0]

    def make(self, rng, frames: int, fps: float):
        """Build one with the kind's random stream ``rng``; a kind that moves also gets the
        animation's ``frames`` and ``fps``."""
        return self.build(rng, frames, fps) if self.motion else self.build(rng)


_REGISTRY: dict[str, AssetKind] = {}
_scanned = False


def register(kind: AssetKind) -> AssetKind:
    """Add ``kind`` to the catalogue (call it at module level of a catalogue module); returns
    the entry as registered. A name or material already registered is a ValueError."""
    if not isinstance(kind, AssetKind):
        raise TypeError(f"register takes an AssetKind, got {type(kind).__name__}")
    if kind.name in _REGISTRY:
        raise ValueError(f"asset kind {kind.name!r} is registered twice ({_REGISTRY[kind.name].module} and "
                         f"{kind.module or 'a later call'}); give the new kind another name")
    if not kind.classes:
        raise ValueError(f"asset kind {kind.name!r} names no taxonomy class; set classes=('ItsClass',)")
    if kind.shared_streams and kind.order >= FIRST_NEW_ORDER:
        raise ValueError(f"asset kind {kind.name!r}: shared_streams is for the first release's kinds (order < "
                         f"{FIRST_NEW_ORDER}); a new kind draws from its own streams")
    taken = {m.name: k.name for k in _REGISTRY.values() for m in k.materials} | {m.name: "the shared materials" for m in SHARED}
    for m in kind.materials:
        if m.name in taken:
            raise ValueError(f"asset kind {kind.name!r} declares material {m.name!r}, already declared by "
                             f"{taken[m.name]}; use that one by name or give yours another name")
    if not kind.module:
        caller = inspect.currentframe().f_back
        kind = replace(kind, module=caller.f_globals.get("__name__", "") if caller else "")
    _REGISTRY[kind.name] = kind
    return kind


def unregister(name: str) -> None:
    """Remove kind ``name`` (a test's or a notebook's runtime entry). What was computed from
    the catalogue at import (``PRESETS``, ``CLASSES``) keeps it."""
    _REGISTRY.pop(name, None)


def scan() -> None:
    """Import every module of :mod:`generator.scene.catalogue` (sorted by name) once."""
    global _scanned
    if _scanned:
        return
    _scanned = True  # before the imports: a module that reads the catalogue while loading sees what is there
    try:
        package = importlib.import_module(CATALOGUE)
        for name in sorted(m.name for m in pkgutil.iter_modules(package.__path__)):
            importlib.import_module(f"{CATALOGUE}.{name}")
    except BaseException:
        _scanned = False  # the next reader tries again (and meets the same error)
        raise


def all_kinds() -> list[AssetKind]:
    """Every registered kind, in planning order (``order``, then name)."""
    scan()
    return sorted(_REGISTRY.values(), key=lambda k: (k.order, k.name))


def kind(name: str) -> AssetKind:
    """The entry of kind ``name``; KeyError naming the known kinds if there is none."""
    scan()
    try:
        return _REGISTRY[name]
    except KeyError:
        raise KeyError(f"no asset kind {name!r} in the catalogue; known: {', '.join(sorted(_REGISTRY))}") from None


def all_materials() -> dict[str, Material]:
    """Every declared material by name: the shared ones, then each kind's (in planning order)."""
    return {m.name: m for m in SHARED} | {m.name: m for k in all_kinds() for m in k.materials}
