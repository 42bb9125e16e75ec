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


def _build(name: str, seed: int, phase: float, growth: Growth | None = None, max_length: float = 40.0):
    return building_type(name).build(stream(seed, "test", name), phase, (4, 8), max_length, growth)


def _vertices(asset, label: str | None = None) -> np.ndarray:
    return np.concatenate([p.mesh.vertices for p in asset.parts if label is None or p.label == label])


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
            assert info["height"] >= info["floors_built"] * info["floor_height"] and _vertices(a, "Building")[:, 2].max() <= info["height"] + 1e-6


@pytest.mark.parametrize("name", TYPES)
def test_same_stream_same_building_and_growth_keeps_what_was_enclosed(name):
    a, b = _build(name, 3, 0.5), _build(name, 3, 0.5)
    for pa, pb in zip(a.parts, b.parts):
        assert pa.label == pb.label and np.array_equal(pa.mesh.vertices, pb.mesh.vertices)
    built, enclosed, planned = a.info["floors_built"], a.info["floors_enclosed"], a.info["floors_planned"]
    same = _build(name, 3, 0.5, Growth(built, enclosed, lambda k: stream(9, "floor", k)))
    assert all(np.array_equal(p.mesh.vertices, q.mesh.vertices) for p, q in zip(a.parts, same.parts))
    grown = _build(name, 3, 0.5, Growth(planned, planned - 1, lambda k: stream(9, "floor", k)))
    assert grown.info["floors_built"] == planned > built and grown.info["height"] > a.info["height"]
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
