"""Where a site sits (bpy-free): its context kind, chosen per seed, and what it puts on the
ground beyond the fence (the surroundings: :mod:`generator.scene.catalogue.surroundings`).

A seed draws one :data:`CONTEXTS` kind by weight (``--context NAME`` fixes it) from its own
``context`` stream, so no other draw of the site moves with it:

- ``urban``: infill between close neighbours: blocks of 3-7 storeys with shops on the
  ground floor, level streets with parked cars and street lights, a few street trees;
- ``suburban``: an estate: two-storey houses with pitched roofs in a row, front hedges,
  garden trees, quiet streets;
- ``industrial``: sheds of profiled metal on large plots, yards, service roads, few trees;
- ``open``: the edge of town: fields and rolling ground, hedgerows, groups of trees, a
  country road at the gate.

Each kind sets the relief of the ground beyond the fence (``terrain``: a factor on
:mod:`generator.scene.relief`'s terrain; 0 keeps it level, as streets and built plots are)
and what stands on it. The context changes what is around the site, never the site itself:
every asset inside the fence, and its ground truth, is drawn as before (docs/scenes.md,
"Context and surroundings").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.seeding import stream


@dataclass(frozen=True)
class Context:
    """One context kind. Lengths in metres.

    - ``weight``: its share of seeds; ``terrain``: factor on the terrain's rise and waves.
    - ``street``: chance that a side other than the gate's has a street along the fence (the
      gate's side always has one); ``parking``: share of a street's parking places taken.
    - ``neighbour``: the style of the buildings beyond the street (``block``, ``house``,
      ``shed`` or '' for none), ``lot`` (narrowest, widest) frontage, ``gap`` between two,
      ``storeys`` (fewest, most), ``depth`` (shallowest, deepest) and ``setback`` from the
      street or the fence.
    - ``trees``: trees per 100 m of side; ``hedges``: hedges along plot fronts or fields.
    - ``sidewalk``, ``carriageway``: a street's sidewalks (each; 0: none) and carriageway.
    """

    name: str
    weight: float
    words: str
    terrain: float
    street: float
    parking: float
    neighbour: str
    lot: tuple[float, float] = (10.0, 20.0)
    gap: tuple[float, float] = (0.0, 2.0)
    storeys: tuple[int, int] = (1, 2)
    depth: tuple[float, float] = (8.0, 12.0)
    setback: tuple[float, float] = (0.5, 2.0)
    trees: float = 2.0
    hedges: bool = False
    sidewalk: float = 2.0
    carriageway: float = 7.0

    def summary(self) -> dict:
        """site.json's ``context``-related record (``surroundings``)."""
        return {"kind": self.name, "terrain_factor": self.terrain, "neighbours": self.neighbour or None}


CONTEXTS: dict[str, Context] = {c.name: c for c in (
    Context("urban", 0.28, "infill between close neighbours: blocks, level streets, parked cars, street lights",
            terrain=0.0, street=0.6, parking=0.7, neighbour="block", lot=(12.0, 28.0), gap=(0.1, 1.0),
            storeys=(3, 7), depth=(9.0, 14.0), setback=(0.3, 1.0), trees=2.0),
    Context("suburban", 0.28, "an estate of two-storey houses in a row, front hedges, garden trees, quiet streets",
            terrain=0.3, street=0.5, parking=0.35, neighbour="house", lot=(7.5, 10.5), gap=(2.5, 6.0),
            storeys=(2, 2), depth=(7.5, 9.5), setback=(2.0, 4.0), trees=6.0, hedges=True, sidewalk=1.8, carriageway=6.5),
    Context("industrial", 0.24, "sheds of profiled metal on large plots, yards, service roads",
            terrain=0.2, street=0.5, parking=0.3, neighbour="shed", lot=(24.0, 42.0), gap=(4.0, 10.0),
            storeys=(1, 1), depth=(12.0, 17.0), setback=(1.5, 3.0), trees=1.0, sidewalk=1.5, carriageway=7.5),
    Context("open", 0.20, "fields and rolling ground, hedgerows, groups of trees, a country road",
            terrain=1.0, street=0.0, parking=0.1, neighbour="", trees=9.0, hedges=True, sidewalk=0.0,
            carriageway=5.5),
)}


def check_context(name: str | None) -> str | None:
    """``name`` if it names a context kind (or is None: drawn per seed); ValueError otherwise."""
    if name is not None and name not in CONTEXTS:
        raise ValueError(f"unknown context {name!r}; choose one of {', '.join(CONTEXTS)}")
    return name


def choose_context(seed: int, name: str | None = None) -> Context:
    """The context of the site of ``seed``: ``name``, or one drawn by weight from the seed's
    own ``context`` stream."""
    check_context(name)
    rng = stream(seed, "context")
    names = list(CONTEXTS)
    weights = np.array([CONTEXTS[n].weight for n in names], dtype=float)
    drawn = names[int(rng.choice(len(names), p=weights / weights.sum()))]
    return CONTEXTS[name or drawn]
