"""Contexts and surroundings (generator/scene/contexts.py, generator/scene/surroundings.py):
what stands beyond the fence stands outside it, on the terrain, without overlaps, and never
moves anything inside the fence."""

from __future__ import annotations

import numpy as np
import pytest

from generator.scene.catalogue.ground import GROUND_MARGIN, ground_part
from generator.scene.catalogue.streets import ROAD_UP_M, SIDEWALK_UP_M
from generator.scene.contexts import CONTEXTS, check_context, choose_context
from generator.scene.kinds import kind
from generator.scene.site import plan_site, site_ground, site_params

SURROUNDING = {"Street", "Car", "StreetLight", "Tree", "Hedge", "Neighbour"}


def world_vertices(placed) -> list[np.ndarray]:
    """Every root part's vertices in world metres (surroundings have no child parts)."""
    s, c = np.sin(placed.yaw), np.cos(placed.yaw)
    out = []
    for part in placed.asset.parts:
        assert part.parent is None and part.keys is None  # nothing beyond the fence moves
        v = part.mesh.vertices + np.asarray(part.location)
        out.append(np.column_stack([c * v[:, 0] - s * v[:, 1] + placed.position[0],
                                    s * v[:, 0] + c * v[:, 1] + placed.position[1], v[:, 2]]))
    return out


def terrain_height(plan, xy: np.ndarray) -> np.ndarray:
    beyond = np.maximum(np.max(np.abs(xy), axis=1) - plan.params.size / 2, 0.0)
    return plan.relief.terrain.height(xy, beyond)


@pytest.fixture(scope="module")
def plans():
    """One medium plan per context (seed 7), and seed 7 as drawn."""
    return {name: plan_site(7, site_params("medium", context=name)) for name in CONTEXTS}


def test_context_draws_and_flags():
    assert abs(sum(c.weight for c in CONTEXTS.values()) - 1.0) < 1e-9
    drawn = {choose_context(s).name for s in range(60)}
    assert drawn == set(CONTEXTS)  # every kind occurs
    assert choose_context(5) == choose_context(5)
    assert choose_context(5, "open").name == "open"
    with pytest.raises(ValueError, match=r"^unknown context 'harbour'; choose one of urban, suburban"):
        check_context("harbour")
    with pytest.raises(ValueError, match="unknown context"):
        site_params("medium", context="harbour")
    assert plan_site(3, site_params("small", context="urban")).summary()["context"] == "urban"


def test_surroundings_stay_outside_the_fence(plans):
    for name, plan in plans.items():
        half = plan.params.size / 2
        kinds = {p.asset.kind for p in plan.placed}
        assert "Street" in kinds, name  # the gate's side has a street (a country road in the open)
        assert kinds & {"Neighbour", "Tree", "Hedge"}, name
        for p in plan.placed:
            if p.asset.kind not in SURROUNDING:
                continue
            for v in world_vertices(p):
                beyond = np.max(np.abs(v[:, :2]), axis=1) - half
                assert beyond.min() > 0.0, (name, p.asset.kind)  # outside the site's square (the fence is 0.5 m inside it)


def box(footprint, shrink: float = 0.0) -> np.ndarray:
    """(x0, y0, x1, y1) of a footprint (the surroundings' stand square to the site's axes)."""
    c = footprint.corners()
    return np.concatenate([c.min(axis=0) + shrink, c.max(axis=0) - shrink])


def overlap(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3])


def test_surroundings_do_not_overlap(plans):
    """Footprints of surroundings (the streets aside) overlap nothing; every car is on a street."""
    for name, plan in plans.items():
        ours = [p for p in plan.placed if p.asset.kind in SURROUNDING]
        for p in ours:
            yaw = p.yaw % (np.pi / 2)
            assert min(yaw, np.pi / 2 - yaw) < 1e-9  # square to the site
        streets = [box(p.footprint) for p in ours if p.asset.kind == "Street"]
        solid = [(p.asset.kind, box(p.footprint, 0.45)) for p in ours if p.asset.kind not in ("Street", "Car")]
        for i, (ka, a) in enumerate(solid):
            for kb, b in solid[i + 1:]:
                assert not overlap(a, b), (name, ka, kb)
        for p in ours:
            if p.asset.kind == "Car":
                c = box(p.footprint, 0.05)
                assert any(np.all(c[:2] >= s[:2]) and np.all(c[2:] <= s[2:]) for s in streets), name


def test_surroundings_stand_on_the_terrain(plans):
    """No object floats: its lowest vertices are at or below the ground at its footprint's
    corners; a street's top is the ground plus the kerb's or the road's height, exactly."""
    for name, plan in plans.items():
        for p in plan.placed:
            if p.asset.kind not in SURROUNDING - {"Street"}:
                continue
            v = np.concatenate(world_vertices(p))
            ground = terrain_height(plan, p.footprint.corners())
            assert v[:, 2].min() <= ground.min() + 1e-9 + (0.04 if p.asset.kind == "Car" else 0.0), (name, p.asset.kind)
        for p in plan.placed:
            if p.asset.kind != "Street":
                continue
            v = np.concatenate(world_vertices(p))
            up = v[:, 2] - terrain_height(plan, v[:, :2])
            tops = up[up > -0.01]
            assert np.all(np.isclose(tops, ROAD_UP_M, atol=1e-9) | np.isclose(tops, SIDEWALK_UP_M, atol=1e-9)), name


def test_urban_ground_beyond_the_fence_is_level(plans):
    plan = plans["urban"]
    assert plan.relief.terrain.rise == 0.0 and all(w[3] == 0.0 for w in plan.relief.terrain.waves)
    v = site_ground(plan).mesh.vertices
    beyond = np.max(np.abs(v[:, :2]), axis=1) - plan.params.size / 2
    assert beyond.max() == pytest.approx(GROUND_MARGIN)
    assert np.all(v[beyond > 0.01, 2] == 0.0)
    open_v = site_ground(plans["open"]).mesh.vertices
    assert np.abs(open_v[np.max(np.abs(open_v[:, :2]), axis=1) > 60.0, 2]).max() > 0.3  # rolling ground in the open


def test_context_never_moves_the_site(plans):
    """The site inside the fence is the same whatever surrounds it: same assets, same places."""
    def inside(plan):
        return [(p.asset.kind, p.position, p.yaw, p.uid) for p in plan.placed if p.asset.kind not in SURROUNDING]

    first = inside(plans["urban"])
    assert len(first) > 20
    for name, plan in plans.items():
        assert inside(plan) == first, name


def test_neighbours_face_the_site_with_windows():
    rng = np.random.default_rng(0)
    for style in ("block", "house", "shed"):
        a = kind("Neighbour").build(rng, style=style, frontage=14.0, depth=10.0, storeys=3)
        mesh = a.parts[0].mesh
        assert "glass" in mesh.materials, style
        front = mesh.vertices[:, 1].max()
        assert 10.0 / 2 <= front <= 10.0 / 2 + 0.35  # the front (+y) carries the windows, doors and sills
        assert mesh.vertices[:, 2].min() < -0.9  # the plinth reaches below the base


def test_street_profile_and_length():
    a = kind("Street").build(np.random.default_rng(1), length=40.0, sidewalk=2.0, carriageway=7.0)
    v = a.parts[0].mesh.vertices
    assert v[:, 0].min() == pytest.approx(-20.0) and v[:, 0].max() == pytest.approx(20.0)
    assert v[:, 1].max() == pytest.approx(5.5) and v[:, 1].min() == pytest.approx(-5.5)
    top = v[v[:, 2] > 0.0]
    assert set(np.round(top[:, 2], 6)) == {ROAD_UP_M, SIDEWALK_UP_M}
    kerb = top[np.isclose(top[:, 2], SIDEWALK_UP_M)]
    assert np.all(np.abs(kerb[:, 1]) >= 3.5 - 1e-9)  # sidewalks only beyond the 7 m carriageway


def test_ground_without_surroundings_unchanged():
    """The ground's own mesh is that of the site (the surroundings are their own objects)."""
    assert ground_part(50.0).mesh.vertices.shape == (4, 3)
