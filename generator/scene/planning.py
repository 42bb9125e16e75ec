"""How the catalogue's kinds are placed on a site: the state the placement rules share while
a plan is made (:class:`SiteState`) and the rules themselves (bpy-free).

A kind's entry (:class:`generator.scene.kinds.AssetKind`) names its rule in ``place``:

- :class:`Scatter`: a count per preset (the entry's ``counts``), each placed inside the road
  loop (following the site's layout) or in the band along the fence: the rule for a new
  kind, whose every draw comes from streams named after it;
- :class:`Mix`: one of the first release's props: the site draws ``density`` props per
  170 m^2 and picks each one's kind by ``weight`` from the shared stream;
- :class:`Custom`: the kind's own planner function (buildings, cranes, trucks, the fence);
- :class:`Grouped`: one planner for several kinds at once (the surroundings beyond the fence).

:func:`generator.scene.site.plan_site` runs the rules in the entries' ``order``; kinds whose
rules share a ``group`` (the mix) are planned together, when the group's first kind's turn comes.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar

import numpy as np

from ..geometry.seeding import stream
from .assets import Asset
from .placement import PlacedAsset, Placer, SiteArea


@dataclass
class SiteState:
    """What the kinds' placement rules share while the plan of ``seed`` is made: the
    parameters, the plan so far, the site's shared random stream (``site-layout``: only the
    first release's kinds draw from it, in their fixed order), the :class:`Placer` of the
    ground left free, the site's geometry (``half`` its half-side, ``road_half`` the road's
    centre line, ``gate`` the gate's x range, ``area`` where props go) and what the buildings
    left for the kinds after them (``buildings`` placed, the ``tallest`` one's height at the
    timeline's last stage)."""

    seed: int
    params: Any  # SiteParams
    plan: Any  # SitePlan
    rng: np.random.Generator
    placer: Placer
    half: float
    road_half: float
    gate: tuple[float, float]
    area: SiteArea
    buildings: list[PlacedAsset] = field(default_factory=list)
    tallest: float = 10.0

    def count_range(self, kind) -> tuple[int, int]:
        """(fewest, most) of ``kind`` on this site: its SiteParams field, else its entry in
        ``SiteParams.counts`` (none if absent)."""
        if kind.count_param is not None:
            return getattr(self.params, kind.count_param)
        return dict(self.params.counts).get(kind.name, (0, 0))

    def count(self, kind) -> int:
        """How many of ``kind`` this site has, drawn from the shared stream for a
        first-release kind, else from the kind's own ``(name, "count")`` stream."""
        lo, hi = self.count_range(kind)
        rng = self.rng if kind.shared_streams else stream(self.seed, "asset", kind.name, "count")
        return int(rng.integers(lo, hi + 1))

    def place(self, name: str, asset: Asset, candidates) -> PlacedAsset | None:
        """Put ``asset`` (of kind ``name``) at the first free candidate and add it to the
        plan, or count it in the plan's ``skipped`` under ``name``."""
        if asset.kind != name:
            raise ValueError(f"the builder of asset kind {name!r} made an Asset of kind {asset.kind!r}; "
                             f"build it as Asset({name!r}, ...)")
        placed = self.placer.try_place(asset, candidates)
        if placed is None:
            self.skip(name)
        else:
            self.plan.placed.append(placed)
        return placed

    def skip(self, name: str) -> None:
        self.plan.skipped[name] = self.plan.skipped.get(name, 0) + 1


class Placement:
    """A placement rule: ``plan(site, kinds)`` places the ``kinds`` that share it (one kind,
    or every member of the rule's ``group``)."""

    group: ClassVar[str | None] = None

    def plan(self, site: SiteState, kinds: list) -> None:
        raise NotImplementedError


@dataclass(frozen=True)
class Custom(Placement):
    """The kind's own planner: ``planner(site, kind)``."""

    planner: Callable[[SiteState, Any], None]

    def plan(self, site: SiteState, kinds: list) -> None:
        for kind in kinds:
            self.planner(site, kind)


@dataclass(frozen=True)
class Grouped(Placement):
    """Kinds planned together by one ``planner(site, kinds)`` (every kind whose rule is
    this one, in their order), at the turn of the first of them; ``name`` names the group."""

    planner: Callable[[SiteState, list], None]
    name: str

    @property
    def group(self) -> str:  # type: ignore[override]
        return self.name

    def plan(self, site: SiteState, kinds: list) -> None:
        self.planner(site, kinds)


@dataclass(frozen=True)
class Scatter(Placement):
    """A count of the kind (its entry's ``counts`` per preset), each built from the kind's
    stream ``(name, k)`` and placed at the first free one of ``tries`` candidates drawn
    from it: in the band along the fence if ``band`` (and the site has one), else inside the
    road loop, following the site's layout if ``follow_layout``, else uniformly."""

    band: bool = False
    follow_layout: bool = True
    tries: int = 60

    def plan(self, site: SiteState, kinds: list) -> None:
        for kind in kinds:
            for k in range(site.count(kind)):
                rng = stream(site.seed, "asset", kind.name, k)
                asset = kind.make(rng, site.params.frames, site.params.fps)
                area = site.area if self.follow_layout else SiteArea(site.area.inner, site.area.band, "scattered")
                site.place(kind.name, asset, area.band_or_inside(rng, self.band, self.tries))


@dataclass(frozen=True)
class Mix(Placement):
    """One of the first release's props: the site has ``density`` props per 170 m^2, each
    one's kind drawn by ``weight`` among the mix's kinds (in their ``order``) from the shared
    stream, which then draws the clustered layout's centres; prop ``i`` is built from the
    stream ``(name, i)`` and placed in the band along the fence if ``band``, else inside."""

    weight: float
    band: bool = False
    group: ClassVar[str | None] = "mix"

    def plan(self, site: SiteState, kinds: list) -> None:
        strangers = [k.name for k in kinds if not k.shared_streams]
        if strangers:
            raise ValueError(f"asset kind(s) {', '.join(strangers)} joined the prop mix, whose draws are shared: "
                             "adding one would change every seed's props; place a new kind with Scatter")
        params = site.params
        area = params.size * params.size  # not ** 2: the C library's pow is picked by CPU
        n_props = int(round(params.density * area / 170.0))
        weights = np.array([k.place.weight for k in kinds], dtype=float)
        chosen = site.rng.choice(len(kinds), size=n_props, p=weights / weights.sum())
        site.area.centres = site.rng.uniform(-site.area.inner, site.area.inner, (max(2, int(area / 2500)), 2))
        for i, which in enumerate(chosen):
            kind = kinds[which]
            rng = stream(site.seed, "asset", kind.name, i)
            asset = kind.make(rng, params.frames, params.fps)
            site.place(kind.name, asset, site.area.band_or_inside(rng, kind.place.band, 60))
