"""Buildings under construction, placed in the middle of the site and grown over a
timeline's stages: one building type per building (:mod:`generator.scene.building_types`:
a concrete frame with brick infill, precast panels or a curtain wall, a steel frame, ...),
drawn by weight per building or fixed by ``SiteParams.building_type``."""

from __future__ import annotations

import math

from ...geometry.seeding import stream
from ..assets import Asset
from ..building_types import Growth, building_type, choose_type, type_materials
from ..kinds import AssetKind, register
from ..materials import CONCRETE_LAYERS, Material, Pattern
from ..planning import Custom
from ..timeline import Rebuilt


def type_of(plan, k: int) -> str:
    """The type of building ``k`` of ``plan``'s seed: ``SiteParams.building_type``, else
    drawn by weight from the building's own stream (seed, "asset", "Building", k, "type")."""
    fixed = plan.params.building_type
    return fixed if fixed is not None else choose_type(stream(plan.seed, "asset", "Building", k, "type")).name


def build_one(plan, k: int, brng, phase: float, max_length: float, growth: Growth | None) -> Asset:
    """Building ``k`` of its type, from its stream ``brng`` (after the phase draw)."""
    name = type_of(plan, k)
    asset = building_type(name).build(brng, phase, plan.params.floors, max_length, growth)
    asset.info["type"] = name
    asset.info["design"] = (k, phase, max_length)  # what a later stage rebuilds it from
    return asset


def building_schedule(seed: int, index: int, own_built: int, planned: int, stage: int) -> tuple[int, int]:
    """(levels built, levels enclosed) of building ``index`` at ``stage``, from its stage-0
    state: each stage adds 1-2 levels of structure (the envelope two levels behind) until
    ``planned``, then one more enclosed level a stage (every building type alike)."""
    built, enclosed = own_built, max(0, own_built - 2)
    for s in range(1, stage + 1):
        r = stream(seed, "timeline", s, "Building", index)
        if built < planned:
            built = min(planned, built + int(r.integers(1, 3)))
            enclosed = max(enclosed, built - 2)
        else:
            enclosed = min(built, enclosed + 1)
    return built, enclosed


def designed_building(plan, k: int, phase: float, max_length: float, growth: Growth | None) -> Asset:
    """Building ``k`` of ``plan``'s seed as designed at stage 0 (``growth`` None) or grown."""
    brng = stream(plan.seed, "asset", "Building", k)
    if plan.params.phase is None:
        brng.uniform(0.25, 1.0)  # the phase draw of plan_buildings
    return build_one(plan, k, brng, phase, max_length, growth)


def grow_buildings(plan, buildings: list, stage: int) -> None:
    """Replace each placed building's asset by its state at ``stage`` (same place)."""
    for placed in buildings:
        k, phase, max_length = placed.asset.info["design"]
        base = designed_building(plan, k, phase, max_length, None)
        built, enclosed = building_schedule(plan.seed, k, base.info["floors_built"], base.info["floors_planned"], stage)
        growth = Growth(built, enclosed, lambda f, k=k: stream(plan.seed, "asset", "Building", k, "floor", f))
        placed.asset = designed_building(plan, k, phase, max_length, growth)


def plan_buildings(site, kind: AssetKind) -> None:
    """The buildings in the middle of the site (a seeded position and heading among 300
    tries each); the crane hook height and the tallest building follow from them, as at the
    timeline's last stage, and each building is then as at the plan's stage."""
    params, plan, inner = site.params, site.plan, site.area.inner
    n_build = site.count(kind)
    for k in range(n_build):
        brng = stream(site.seed, "asset", kind.name, k)
        phase = params.phase if params.phase is not None else float(brng.uniform(0.25, 1.0))
        max_length = 2 * inner * (0.9 if n_build == 1 else 0.6)
        asset = build_one(plan, k, brng, phase, max_length, None)
        yaw0 = 0.0 if params.layout == "grid" else float(brng.uniform(-0.3, 0.3))
        cands = [((brng.uniform(-inner, inner), brng.uniform(-inner, inner)), yaw0 + brng.choice([0, math.pi / 2])) for _ in range(300)]
        placed = site.place(kind.name, asset, cands)
        if placed is not None:
            site.buildings.append(placed)
    if plan.stages > 1:
        grow_buildings(plan, site.buildings, plan.stages - 1)  # every building as at the timeline's last stage
    site.tallest = max((p.asset.info["height"] for p in site.buildings), default=10.0)
    plan.hook_height = site.tallest + 4.0
    if plan.stages > 1:
        grow_buildings(plan, site.buildings, plan.stage)


register(AssetKind(
    name="Building", classes=("Building", "Rebar", "Formwork", "Scaffolding"), build=None,
    place=Custom(plan_buildings), order=10, count_param="buildings",
    counts={"small": (1, 1), "medium": (2, 2), "large": (3, 4)},
    materials=(Material("concrete_dark", (0.32, 0.31, 0.3), 0.85, 0.0, Pattern(3.0, (0.24, 0.23, 0.22), 0.5),
                        layers=CONCRETE_LAYERS),
               Material("formwork", (0.75, 0.45, 0.05), 0.6, 0.0, Pattern(5.0, (0.55, 0.4, 0.2), 0.4))) + type_materials(),
    stage=Rebuilt("1-2 levels of structure a stage until the planned height, the envelope two levels behind, "
                  "then the remaining facades one level a stage (each building type says what a level is)"),
    shared_streams=True,
))
