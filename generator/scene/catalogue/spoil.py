"""Spoil heaps: the soil dug out of a site's basement excavation, heaped beside it. Labelled
``Ground`` (it is the site's soil). The kind's placement rule plans the site's digs (a pit
and a trench; generator/scene/relief.py) and puts the heap beside the pit; heaps and digs
stay as they are over a timeline."""

from __future__ import annotations

import numpy as np

from ..assets import Asset
from ..kinds import AssetKind, register
from ..planning import Custom
from ..relief import plan_digs
from .ground import SPOIL
from .piles import material_pile


def spoil_heap(rng: np.random.Generator) -> Asset:
    """A heap of excavated soil: a cone or a ridge 1.5-3.5 m tall at 33-38 degrees, lumpier
    than a sand pile."""
    return material_pile(rng, "SpoilHeap", SPOIL.name, "Ground", heights=(1.5, 3.5), repose=(33.0, 38.0),
                         ridges=(2.0, 6.0), rough=0.12)


register(AssetKind(name="SpoilHeap", classes=("Ground",), build=spoil_heap, place=Custom(plan_digs), order=35))
