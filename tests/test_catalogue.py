"""The asset catalogue (generator/scene/kinds.py, generator/scene/catalogue/): every kind is one
entry found by scanning its package; the plan, presets, taxonomy, timeline and materials read
the entries; a new kind is one new file and changes no other kind's draws."""

import json
import os
import pkgutil
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from generator.scene import catalogue, plan_site, site_params
from generator.scene.assets import Asset, Part
from generator.scene.catalogue.fence import fence_part
from generator.scene.catalogue.ground import ASPHALT, ROADS, SURFACES, GroundSurface, ground_part
from generator.scene.kinds import AssetKind, all_kinds, all_materials, kind, register, unregister
from generator.scene.materials import Material
from generator.scene.meshes import MeshBuilder
from generator.scene.planning import Mix, Scatter
from generator.scene.building_types import all_types
from generator.scene.taxonomy import CLASSES, FIXED, added_classes

ROOT = Path(__file__).resolve().parents[1]

# the prop mix's kinds in the order the site's shared stream picks them (the first release's
# hand-written order): reordering them would change every seed's props
MIX_ORDER = ["Container", "Cabin", "SandPile", "GravelPile", "BrickPallet", "PipeStack", "TimberStack",
             "RebarBundle", "Barrier", "TrafficCone", "PortableToilet", "Skip", "Generator", "Worker"]


def fingerprint(plan) -> list:
    """Every placed asset's kind, uid, place, footprint and geometry (bit for bit)."""
    out = []
    for p in plan.placed:
        verts = [part.mesh.vertices.tobytes() for part in p.asset.parts if part.mesh is not None]
        out.append((p.asset.kind, p.uid, p.position, p.yaw, p.footprint.center, p.footprint.size, hash(tuple(verts))))
    return out + [plan.hook_height, plan.spawn_box, plan.camera, sorted(plan.skipped.items())]


def crate(rng: np.random.Generator) -> Asset:
    size = rng.uniform(0.8, 1.2)
    mesh = MeshBuilder().box((size, size, size), (0, 0, size / 2), material="wood").build()
    return Asset("TestCrate", [Part("Container", mesh)], (size, size))


@pytest.fixture
def test_crate():
    """A new kind registered at runtime, enabled by no preset (removed afterwards), planned
    among the first release's kinds (after the excavators, before the trucks and the props,
    which draw from the shared stream after it)."""
    register(AssetKind(name="TestCrate", classes=("Container",), build=crate, place=Scatter(), order=35))
    yield kind("TestCrate")
    unregister("TestCrate")


def asked(plan) -> dict:
    """How many assets of each kind the plan drew (placed or skipped)."""
    out = dict(plan.skipped)
    for p in plan.placed:
        out[p.asset.kind] = out.get(p.asset.kind, 0) + 1
    return out


def test_every_class_has_an_entry_and_every_kind_a_class():
    covered = {c for k in all_kinds() for c in k.classes}
    assert set(CLASSES) <= covered, f"classes without a catalogue entry: {set(CLASSES) - covered}"
    assert covered <= set(CLASSES)
    assert CLASSES[:len(FIXED)] == tuple(name for name, _ in FIXED)  # the fixed ids, in their order
    assert added_classes() == {}  # this checkout adds none
    # Rebar, Formwork and Scaffolding are parts of the Building kind; Rebar also has its own kind
    assert kind("Building").classes == ("Building", "Rebar", "Formwork", "Scaffolding")
    assert kind("RebarBundle").label == "Rebar"


def test_entries_are_found_by_scanning_their_package():
    modules = {f"{catalogue.__name__}.{m.name}" for m in pkgutil.iter_modules(catalogue.__path__)}
    assert len(modules) >= 10
    assert {k.module for k in all_kinds()} == modules  # each module registers, nothing else does
    names = [k.name for k in all_kinds()]
    assert len(names) == len(set(names))
    # planning order: the first release's kinds in their fixed order, the mix as hand-written
    assert names[:7] == ["Ground", "Fence", "Building", "Crane", "Excavator", "SpoilHeap", "Truck"]
    assert [k.name for k in all_kinds() if isinstance(k.place, Mix)] == MIX_ORDER
    # the first release's kinds share the site's streams; the later ones draw from their own:
    # the spoil heap (its rule plans the digs) and the machinery, planned before the trucks'
    # and props' turn (they need room), and the surroundings, planned last
    assert {k.name for k in all_kinds() if k.shared_streams} == set(names[:5]) | {"Truck"} | set(MIX_ORDER)
    assert all(k.order < 1000 for k in all_kinds() if k.shared_streams)
    surroundings = {"Neighbour", "Tree", "Hedge", "Street", "Car", "StreetLight"}
    assert names[-len(surroundings):] == sorted(surroundings, key=lambda n: kind(n).order)
    assert not kind("SpoilHeap").shared_streams and kind("Excavator").order < kind("SpoilHeap").order < kind("Truck").order


def test_presets_and_materials_come_from_the_entries():
    assert site_params("large").trucks == kind("Truck").counts["large"] == (3, 5)
    assert site_params("small").excavators == kind("Excavator").counts["small"] == (0, 1)
    assert site_params("medium").buildings == (2, 2)
    assert site_params("small").counts == tuple(sorted((k.name, k.counts["small"]) for k in all_kinds()
                                                       if k.count_param is None and k.counts.get("small", (0, 0))[1] > 0))
    materials = all_materials()
    assert materials["sand"] is kind("SandPile").materials[0]
    assert {m.name for k in all_kinds() for m in k.materials} <= set(materials)
    # every material a site's meshes name is declared, and every declared one is used
    used = {"default"} | set(fence_part(np.zeros(2), np.ones(2)).mesh.materials)
    used |= {m for surface in SURFACES for road in ROADS  # every surface, road and tracks; asphalt lends its colour
             for m in ground_part(50.0, GroundSurface(surface, road), 18.5).mesh.materials} | {ASPHALT.name}
    for seed in (0, 1, 2, 3):
        plan = plan_site(seed, site_params("medium", frames=20))
        for p in plan.placed:
            used.update(m for part in p.asset.parts if part.mesh is not None for m in part.mesh.materials)
            keyed = any(part.keys is not None for part in p.asset.parts)
            assert keyed == bool(kind(p.asset.kind).motion), p.asset.kind  # moves iff it declares how
    for r in range(8):  # every building type's and neighbour style's drawn materials
        for t in all_types():
            used.update(t.build(np.random.default_rng(r), 0.6, (3, 5), 40.0, None).parts[0].mesh.materials)
        for style in ("block", "house", "shed"):
            used.update(kind("Neighbour").build(np.random.default_rng(r), style=style).parts[0].mesh.materials)
    assert used <= set(materials), used - set(materials)
    assert len(set(materials) - used) <= 3, set(materials) - used  # a few container colours may not show up


def test_a_disabled_new_kind_changes_no_plan(test_crate):
    unregister("TestCrate")
    cases = [(seed, stage, stages) for seed in (0, 3) for stage, stages in ((0, 1), (1, 2))]
    before = {case: fingerprint(plan_site(case[0], site_params("small", frames=20), *case[1:])) for case in cases}
    register(test_crate)
    assert kind("TestCrate").module == __name__
    for case, fp in before.items():
        assert fingerprint(plan_site(case[0], site_params("small", frames=20), *case[1:])) == fp, case


def test_an_enabled_new_kind_draws_only_its_own_streams(test_crate):
    plain = plan_site(4, site_params("small", frames=20))
    preset = dict(site_params("small").counts)
    params = site_params("small", frames=20, counts=preset | {"TestCrate": (1, 3)})
    assert dict(params.counts) == preset | {"TestCrate": (1, 3)}
    plan = plan_site(4, params)
    crates = [i for i, p in enumerate(plan.placed) if p.asset.kind == "TestCrate"]
    before = [p for p in plain.placed if kind(p.asset.kind).order < test_crate.order]
    assert crates and crates[0] == len(before) > 0  # planned in its order
    # what was planned before it is as on the plain site, and every kind after it drew as
    # many assets (the same prop kinds from the shared stream): it took none of its draws
    assert fingerprint(plan)[:crates[0]] == fingerprint(plain)[:crates[0]]
    assert {k: n for k, n in asked(plan).items() if k != "TestCrate"} == asked(plain)
    assert plan.summary()["added_kinds"] == plain.summary()["added_kinds"] | {"TestCrate": __name__}
    assert "TestCrate" not in plain.summary()["added_kinds"]
    # over a timeline's stages the crates (no stage rule) stay where they are, with their uids
    crates = {p.uid: p.position for p in plan_site(4, params, 0, 2).placed if p.asset.kind == "TestCrate"}
    assert crates and {p.uid: p.position for p in plan_site(4, params, 1, 2).placed if p.asset.kind == "TestCrate"} == crates


def test_registration_errors_say_what_to_do(test_crate):
    with pytest.raises(ValueError, match="registered twice.*another name"):
        register(AssetKind(name="TestCrate", classes=("Container",), build=crate))
    with pytest.raises(ValueError, match="shared_streams is for the first release"):
        register(AssetKind(name="Other", classes=("Container",), build=crate, shared_streams=True))
    with pytest.raises(ValueError, match="material 'sand', already declared by SandPile"):
        register(AssetKind(name="Other", classes=("Container",), build=crate, materials=(Material("sand", (1, 1, 1), 0.5),)))
    with pytest.raises(ValueError, match="site counts: Truck's count is the site parameter 'trucks'"):
        site_params("small", counts={"Truck": (1, 2)})
    with pytest.raises(ValueError, match="site counts: no asset kind 'Nope'"):
        site_params("small", counts={"Nope": (1, 2)})
    with pytest.raises(ValueError, match="the most TestCrate must be an integer from 2"):
        site_params("small", counts={"TestCrate": (2, 1)})
    register(AssetKind(name="Misnamed", classes=("Container",), build=crate, place=Scatter(), counts={"small": (1, 1)}))
    try:
        with pytest.raises(ValueError, match="builder of asset kind 'Misnamed' made an Asset of kind 'TestCrate'"):
            plan_site(0, site_params("small", counts={"Misnamed": (1, 1)}))
    finally:
        unregister("Misnamed")
    register(AssetKind(name="MixedIn", classes=("Container",), build=crate, place=Mix(weight=1.0), order=999))
    try:
        with pytest.raises(ValueError, match="MixedIn joined the prop mix.*Scatter"):
            plan_site(0, site_params("small"))
    finally:
        unregister("MixedIn")
    register(AssetKind(name="Colourless", classes=("NewThing",), build=crate))
    try:
        with pytest.raises(ValueError, match="adds the class 'NewThing': give the entry a colour"):
            added_classes()
    finally:
        unregister("Colourless")


DROP_IN = '''
import numpy as np
from generator.scene.assets import Asset, Part
from generator.scene.kinds import AssetKind, register
from generator.scene.materials import Material
from generator.scene.meshes import MeshBuilder
from generator.scene.planning import Scatter


def drum(rng):
    r = rng.uniform(0.3, 0.4)
    mesh = MeshBuilder().cylinder(r, (0, 0, 0), (0, 0, 0.9), segments=12, material="drum_blue").build()
    return Asset("Drum", [Part("Drum", mesh)], (2 * r, 2 * r))


register(AssetKind(name="Drum", classes=("Drum",), build=drum, place=Scatter(), counts={"small": (1, 1)},
                   colour=(0, 0, 255), materials=(Material("drum_blue", (0.0, 0.1, 0.6), 0.4),)))
'''

PROBE = '''
import json
from generator.scene import CLASSES, plan_site, site_params
from generator.scene.kinds import all_kinds, all_materials
plan = plan_site(2, site_params("small", frames=20))
print(json.dumps({"kinds": [k.name for k in all_kinds()], "classes": list(CLASSES), "drum": "drum_blue" in all_materials(),
                  "placed": [[p.asset.kind, list(p.position), p.yaw] for p in plan.placed],
                  "summary": plan.summary()}))
'''


def test_a_module_dropped_into_the_package_is_picked_up(tmp_path):
    copy = tmp_path / "generator"
    shutil.copytree(ROOT / "generator", copy, ignore=shutil.ignore_patterns("__pycache__"))
    (copy / "scene" / "catalogue" / "drums.py").write_text(DROP_IN)
    r = subprocess.run([sys.executable, "-c", PROBE], cwd=tmp_path, capture_output=True, text=True, timeout=300,
                       env=dict(os.environ, PYTHONPATH=str(tmp_path)))
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads(r.stdout)
    assert "Drum" in got["kinds"] and got["classes"] == list(CLASSES) + ["Drum"] and got["drum"]
    assert got["summary"]["assets"]["Drum"] == 1 and got["summary"]["added_kinds"]["Drum"] == "generator.scene.catalogue.drums"
    plain = plan_site(2, site_params("small", frames=20))
    assert [p for p in got["placed"] if p[0] != "Drum"] == [[p.asset.kind, list(p.position), p.yaw] for p in plain.placed]
    assert [p[0] for p in got["placed"]].count("Drum") == 1
