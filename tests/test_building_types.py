"""Building types (generator/scene/building_types/): every type builds a building that rests
on the ground inside its footprint, draws the same geometry from the same stream, grows over
a timeline without changing what was already enclosed, and is chosen, fixed and recorded as
documented (bpy-free)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from generator.geometry.seeding import stream
from generator.scene import plan_site, site_params
from generator.scene.building_types import Growth, all_types, building_type, choose_type
from generator.scene.kinds import all_materials, kind

ROOT = Path(__file__).resolve().parents[1]
TYPES = [t.name for t in all_types()]
# types whose levels are groups of bays erected along the building, not storeys: the height
# stays a storey's as levels are added, and the structure grows in length instead
ALONG_THE_GROUND = {"industrial-hall"}


def _build(name: str, seed: int, phase: float, growth: Growth | None = None, max_length: float = 40.0):
    return building_type(name).build(stream(seed, "test", name), phase, (4, 8), max_length, growth)


def _vertices(asset, label: str | None = None) -> np.ndarray:
    return np.concatenate([p.mesh.vertices for p in asset.parts if label is None or p.label == label])


def _reach(asset) -> float:
    """How far along x the Building part reaches 1 m above the ground."""
    v = _vertices(asset, "Building")
    return float(v[v[:, 2] > 1.0, 0].max())


def test_at_least_four_types_with_their_materials_declared():
    assert len(TYPES) >= 4 and "concrete-brick" in TYPES
    declared = all_materials()
    for t in all_types():
        assert t.structure and t.weight > 0
        for name in {n for seed in (0, 1) for p in _build(t.name, seed, 0.8).parts for n in p.mesh.materials}:
            assert name in declared, f"{t.name} uses the undeclared material {name!r}"


@pytest.mark.parametrize("name", TYPES)
def test_building_rests_on_the_ground_within_its_length(name):
    """Every vertex, temporary works included, lies within half the building's maximum
    length of its origin (what plan_buildings sizes it by), none below the ground, and the
    structure touches the ground."""
    labels = set(kind("Building").classes)
    for seed in range(4):
        for phase in (0.25, 0.6, 1.0):
            a = _build(name, seed, phase)
            v = _vertices(a)
            assert np.abs(v[:, :2]).max() <= 20.0 + 1e-6, f"{name} seed {seed} is longer than 40 m"
            assert v[:, 2].min() >= -1e-9 and v[:, 2].min() <= 1e-6
            assert {p.label for p in a.parts} <= labels and "Building" in {p.label for p in a.parts}
            info = a.info
            assert 1 <= info["floors_built"] <= info["floors_planned"] and 0 <= info["floors_enclosed"] <= info["floors_built"]
            stacked = 1 if name in ALONG_THE_GROUND else info["floors_built"]
            assert info["height"] >= stacked * info["floor_height"] and _vertices(a, "Building")[:, 2].max() <= info["height"] + 1e-6


@pytest.mark.parametrize("name", TYPES)
def test_same_stream_same_building_and_growth_keeps_what_was_enclosed(name):
    a, b = _build(name, 3, 0.5), _build(name, 3, 0.5)
    for pa, pb in zip(a.parts, b.parts):
        assert pa.label == pb.label and np.array_equal(pa.mesh.vertices, pb.mesh.vertices)
    built, enclosed, planned = a.info["floors_built"], a.info["floors_enclosed"], a.info["floors_planned"]
    same = _build(name, 3, 0.5, Growth(built, enclosed, lambda k: stream(9, "floor", k)))
    assert all(np.array_equal(p.mesh.vertices, q.mesh.vertices) for p, q in zip(a.parts, same.parts))
    grown = _build(name, 3, 0.5, Growth(planned, planned - 1, lambda k: stream(9, "floor", k)))
    assert grown.info["floors_built"] == planned > built
    if name in ALONG_THE_GROUND:  # the structure (above the slab) reaches further along x
        assert grown.info["height"] >= a.info["height"] and _reach(grown) > _reach(a)
    else:
        assert grown.info["height"] > a.info["height"]
    # what stood below the old top enclosed level is still there, vertex for vertex
    cut = max(enclosed, 1) * a.info["floor_height"] - 0.05
    old = {tuple(np.round(p, 6)) for p in _vertices(a, "Building") if p[2] < cut}
    new = {tuple(np.round(p, 6)) for p in _vertices(grown, "Building") if p[2] < cut}
    assert old and old <= new
    with pytest.raises(ValueError, match="building growth"):
        _build(name, 3, 0.5, Growth(planned + 1, 0, lambda k: stream(9, "floor", k)))


def test_types_are_drawn_by_weight_and_fixed_by_the_parameter():
    draws = [choose_type(stream(s, "asset", "Building", 0, "type")).name for s in range(400)]
    weights = {t.name: t.weight for t in all_types()}
    total = sum(weights.values())
    for name, w in weights.items():
        assert abs(draws.count(name) / len(draws) - w / total) < 0.07, name
    plan = plan_site(4, site_params("medium", building_type="precast"))
    entries = plan.summary()["buildings"]
    assert entries and {e["type"] for e in entries} == {"precast"}
    assert plan.summary()["params"]["building_type"] == "precast"
    assert "building_type" not in plan_site(4, site_params("medium")).summary()["params"]
    with pytest.raises(ValueError, match="^unknown building type 'igloo'; choose one of "):
        site_params("medium", building_type="igloo")


def test_site_json_states_each_buildings_type(tmp_path):
    """A saved site (python -m generator.scene --building-type) records its buildings and
    their types; a wrong type is a one-line error with exit code 2."""
    r = subprocess.run([sys.executable, "-m", "generator.scene", "--seed", "4", "--preset", "small", "--building-type",
                        "curtain-wall", "--no-preview", "--out", str(tmp_path / "site")], capture_output=True, text=True,
                       cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    info = json.loads((tmp_path / "site" / "site.json").read_text())
    assert [b["type"] for b in info["buildings"]] == ["curtain-wall"] * info["assets"]["Building"]
    assert all(b["height_m"] > 0 and b["floors_built"] >= 1 for b in info["buildings"])
    r = subprocess.run([sys.executable, "-m", "generator.scene", "--seed", "4", "--building-type", "igloo", "--out",
                        str(tmp_path / "bad")], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and "invalid choice" in r.stderr and "Traceback" not in r.stderr


def _material_vertices(mesh, material: str) -> np.ndarray:
    """The vertices of ``mesh``'s faces of ``material``."""
    if material not in mesh.materials:
        return np.zeros((0, 3))
    slot, nq = mesh.materials.index(material), len(mesh.quads)
    used = np.concatenate([mesh.quads[mesh.face_material[:nq] == slot].ravel(),
                           mesh.tris[mesh.face_material[nq:] == slot].ravel()])
    return mesh.vertices[np.unique(used)]


def _hall_steel(asset) -> np.ndarray:
    return _material_vertices(next(p.mesh for p in asset.parts if p.label == "Building"), "steel_primer")


def test_industrial_hall_frames_ridge_and_footprint():
    """An industrial hall's frames stand the drawn bay apart from the x0 gable on, one more
    than its bays framed; the rafters' top meets at eaves + span/2 tan(pitch) plus the
    rafter's depth (normal to the slope); drawn sizes are in their real ranges unless shrunk
    to fit; everything, temporary works included, stays within max_length on both axes."""
    from generator.geometry.portable_math import sincos
    from generator.scene.building_types.industrial_hall import PURLIN, RAFTER, SKIN

    for seed in range(5):
        for max_length in (12.0, 25.0, 41.4, 60.0):
            a = _build("industrial-hall", seed, 1.0, max_length=max_length)
            info = a.info
            v = _vertices(a)
            assert np.abs(v[:, :2]).max() <= max_length / 2 + 1e-6 and max(a.size) <= max_length + 1e-6
            assert np.all(np.abs(v[:, :2]) <= np.array(a.size) / 2 + 1e-6)
            assert info["floors_planned"] <= info["bays"] and info["bays_framed"] == info["bays"]
            if max_length == 60.0:  # room for every drawn size: none shrunk
                assert 18.0 <= info["span"] <= 30.0 and 6.0 <= info["bay"] <= 7.5 and 4 <= info["bays"] <= 8
            assert 6.0 <= info["floor_height"] <= 10.0 and 5.0 <= info["pitch_deg"] <= 10.0
            steel, w = _hall_steel(a), info["span"] / 2
            feet = steel[(np.abs(steel[:, 2] - 0.2) < 1e-9) & (np.abs(np.abs(steel[:, 1]) - w) <= 0.25 + 1e-9)]
            xs = np.sort(feet[:, 0])
            groups = np.split(xs, np.flatnonzero(np.diff(xs) > 1.0) + 1)
            centres = np.array([(g[0] + g[-1]) / 2 for g in groups])
            assert len(centres) == info["bays"] + 1
            assert np.allclose(np.diff(centres), info["bay"], atol=1e-9)
            assert abs(centres[0] + info["bays"] * info["bay"] / 2) < 1e-9
            s, c = sincos(info["pitch_deg"] * np.pi / 180.0)
            ridge = info["floor_height"] + w * s / c
            assert 0.0 < steel[:, 2].max() - ridge <= RAFTER / c + 1e-9
            assert steel[:, 2].max() <= info["height"] <= ridge + (RAFTER + PURLIN + SKIN) / c + 1e-9


def test_industrial_hall_grows_bay_by_bay():
    """Over a timeline's stages (building_schedule), the hall frames and clads more bays and
    keeps every vertex of the previous stage's Building part; by the last stage every bay is
    framed and the far gable (its roller doors) is clad once every level is enclosed."""
    from generator.scene.building_types.industrial_hall import OVER
    from generator.scene.catalogue.buildings import building_schedule

    for seed in range(4):
        a = _build("industrial-hall", seed, 0.25)
        own, planned = a.info["floors_built"], a.info["floors_planned"]
        prev = a
        for stage in range(1, 9):
            built, enclosed = building_schedule(seed, 0, own, planned, stage)
            g = _build("industrial-hall", seed, 0.25, Growth(built, enclosed, lambda k: stream(9, "floor", k)))
            old = {tuple(np.round(p, 6)) for p in _vertices(prev, "Building")}
            new = {tuple(np.round(p, 6)) for p in _vertices(g, "Building")}
            assert old <= new
            more = (g.info["bays_framed"] - prev.info["bays_framed"], g.info["bays_clad"] - prev.info["bays_clad"])
            assert more[0] >= 0 and more[1] >= 0
            if (built, enclosed) != (prev.info["floors_built"], prev.info["floors_enclosed"]):
                assert max(more) > 0 and len(new) > len(old)
            assert g.info["floor_height"] == a.info["floor_height"] and g.info["bay"] == a.info["bay"]
            prev = g
        assert prev.info["bays_framed"] == prev.info["bays"] and prev.info["bays_clad"] == prev.info["bays"]
        doors = _material_vertices(next(p.mesh for p in prev.parts if p.label == "Building"), "steel_galvanized")
        assert doors[:, 0].max() > _reach(prev) - OVER - 1e-6  # the far gable's roller doors, flush with its cladding


def test_industrial_hall_on_a_timeline():
    """plan_site with a fixed industrial-hall type: the hall is placed and grows over the
    stages in levels (bays), never beyond its planned levels."""
    params = site_params("small", building_type="industrial-hall")
    levels = [[(b["floors_built"], b["floors_enclosed"], b["floors_planned"]) for b in plan_site(4, params, k, 3).summary()["buildings"]]
              for k in range(3)]
    assert levels[0] and all(len(row) == len(levels[0]) for row in levels)
    for before, after in zip(levels, levels[1:]):
        for (b0, e0, p0), (b1, e1, p1) in zip(before, after):
            assert p0 == p1 and b0 <= b1 <= p1 and e0 <= e1 <= b1
