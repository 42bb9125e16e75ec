"""Construction machinery in the asset catalogue (generator/scene/catalogue/): mobile cranes, pump
trucks, rollers, wheel loaders and piling rigs. Each is built in its own frame standing on the
ground, labelled with its class, sized like the real machine, covered by its footprint, the
same for the same seed, and placed on medium sites."""

import numpy as np
import pytest

from generator.geometry.camera import apply_affine, matmul_exact
from generator.scene import plan_site, site_params
from generator.scene.assets import overlaps
from generator.scene.kinds import all_materials, kind
from generator.scene.meshes import rotation_x, rotation_y, rotation_z

MACHINES = ("MobileCrane", "PumpTruck", "Roller", "Loader", "PileDriver")
SEEDS = (0, 1, 2, 3, 4, 5)


def build(name: str, seed: int):
    return kind(name).make(np.random.default_rng(seed), 250, 10.0)


def world_vertices(asset) -> np.ndarray:
    """Every vertex of ``asset`` in its own frame (each part moved by its and its parents'
    transforms, as generator/scene/placement.py's local_bounds does)."""
    mats, out = [], []
    for part in asset.parts:
        m = np.eye(4)
        rx, ry, rz = part.rotation
        m[:3, :3] = matmul_exact(matmul_exact(rotation_z(rz), rotation_y(ry)), rotation_x(rx))
        m[:3, 3] = part.location
        if part.parent is not None:
            m = matmul_exact(mats[part.parent], m)
        mats.append(m)
        if part.mesh is not None:
            out.append(apply_affine(m, part.mesh.vertices))
    return np.concatenate(out)


def extent(asset) -> np.ndarray:
    v = world_vertices(asset)
    return v.max(axis=0) - v.min(axis=0)


@pytest.mark.parametrize("name", MACHINES)
def test_a_machine_stands_on_the_ground_inside_its_footprint(name):
    declared = all_materials()
    for seed in SEEDS:
        asset = build(name, seed)
        assert asset.kind == name and not asset.moves and asset.placement is None
        assert {p.label for p in asset.parts} == {kind(name).label} == {name}
        assert all(p.keys is None for p in asset.parts)  # static
        v = world_vertices(asset)
        assert -1e-3 <= v[:, 2].min() <= 1e-3, (name, seed, v[:, 2].min())
        half = np.asarray(asset.size) / 2
        assert np.all(v[:, :2] >= -half - 1e-9) and np.all(v[:, :2] <= half + 1e-9), (name, seed)
        assert np.all(np.abs(v[:, :2].min(axis=0) + v[:, :2].max(axis=0)) < 1e-6)  # centred on the origin
        assert 500 < asset.triangle_count < 30_000, (name, asset.triangle_count)
        used = {m for p in asset.parts for m in p.mesh.materials}
        assert used <= set(declared), used - set(declared)
        assert {m.name for m in kind(name).materials} <= used  # its own materials show


@pytest.mark.parametrize("name", MACHINES)
def test_the_same_seed_builds_the_same_machine(name):
    def vertices(seed):
        return [(p.mesh.vertices, p.location) for p in build(name, seed).parts]

    a, b, c = vertices(7), vertices(7), vertices(8)
    assert len(a) == len(b) and all(np.array_equal(va, vb) and la == lb for (va, la), (vb, lb) in zip(a, b))
    assert len(a) != len(c) or any(va.shape != vc.shape or not np.array_equal(va, vc) for (va, _), (vc, _) in zip(a, c))


def test_mobile_cranes_are_real_sized():
    for seed in SEEDS:
        crane = build("MobileCrane", seed)
        info, size = crane.info, extent(crane)
        assert 12.0 <= info["carrier_length"] <= 14.0 and info["axles"] in (4, 5)
        assert 20.0 <= info["boom_length"] <= 35.0 and 30.0 <= info["boom_angle_deg"] <= 70.0 and info["sections"] in (3, 4)
        assert 6.0 <= info["outrigger_span"] <= 7.5
        # the boom head's sheaves: the deck (1.95 m), the boom's foot 1.9 m above it, then the boom and its head
        head = 3.85 + (info["boom_length"] + 0.35) * np.sin(np.radians(info["boom_angle_deg"]))
        assert head == pytest.approx(info["head_height"], abs=1e-6)
        assert 0.3 < size[2] - head < 0.8 and 13.0 <= size[2] <= 37.5, (seed, size[2], head)
        assert info["hook_height"] >= 2.0 and info["hook_height"] < info["head_height"] - 3.0
        # plan view: the carrier and the boom's horizontal reach; the outriggers' pads across
        reach = info["boom_length"] * np.cos(np.radians(info["boom_angle_deg"]))
        assert size[0] >= max(info["carrier_length"], reach)
        assert info["outrigger_span"] + 0.6 - 1e-6 <= size[1] <= 8.1 + reach * np.sin(np.radians(20)) + 1.0
    assert len({build("MobileCrane", s).info["sections"] for s in range(12)}) == 2  # 3 and 4 sections both occur


def test_pump_trucks_are_real_sized():
    poses = set()
    for seed in range(12):
        pump = build("PumpTruck", seed)
        info, size = pump.info, extent(pump)
        assert 10.0 <= info["truck_length"] <= 12.0 and info["axles"] in (3, 4)
        assert 20.0 <= info["boom_length"] <= 36.0
        assert size[0] >= info["truck_length"] and size[1] >= 6.0  # outriggers out
        if info["folded"]:
            assert 4.0 < size[2] < 5.5  # the folded boom on the truck
        else:
            # the first section at 55-85 degrees, the second at 10-50 above the horizontal
            assert 3.0 + 0.27 * info["boom_length"] <= size[2] <= 3.6 + 0.62 * info["boom_length"], (seed, size[2])
            assert info["tip_height"] - info["hose"] >= 1.0  # the hose hangs clear of the ground
        poses.add(info["folded"])
    assert poses == {True, False}


def test_rollers_are_real_sized():
    for seed in SEEDS:
        roller = build("Roller", seed)
        size = extent(roller)
        assert 5.5 - 1e-3 <= size[0] <= 6.0 + 1e-3 and 2.1 - 1e-3 <= size[1] <= 2.3 + 1e-3
        assert 2.9 - 1e-3 <= size[2] <= 3.1 + 1e-3  # the canopy's roof
        assert 1.45 <= roller.info["drum_diameter"] <= 1.6


def test_loaders_are_real_sized():
    hinges = []
    for seed in SEEDS:
        loader = build("Loader", seed)
        info, size = loader.info, extent(loader)
        assert 7.0 <= size[0] <= 8.5 and size[0] == pytest.approx(info["length"], abs=0.01)
        assert 2.5 <= size[1] <= 3.0 + 1e-3 and size[1] == pytest.approx(max(2.8, info["bucket_width"]), abs=0.01)
        assert 1.55 <= info["tyre_diameter"] <= 1.7 and 2.5 <= info["bucket_width"] <= 3.0
        assert 3.3 <= info["height"] <= 3.5 and info["height"] - 1e-2 <= size[2] <= 4.5
        assert info["bucket_lowest"] >= 0.0
        hinges.append(info["hinge_height"])
    assert max(hinges) - min(hinges) > 0.5  # the bucket at a seeded height


def test_piling_rigs_are_real_sized():
    tools = set()
    for seed in range(10):
        rig = build("PileDriver", seed)
        info, size = rig.info, extent(rig)
        assert 18.0 <= info["mast_height"] <= 26.0 and size[2] == pytest.approx(info["mast_height"], abs=1e-3)
        assert 5.0 <= info["track_length"] <= 6.0 and size[0] >= info["track_length"] + 1.5  # the mast in front
        assert 3.5 - 1e-3 <= size[1] <= 4.2 + 1e-3
        if info["tool"] == "hammer":
            assert 3.5 <= info["hammer_length"] <= 5.5 and info["pile_length"] >= 5.5
        else:
            assert 0.6 <= info["auger_diameter"] <= 1.0 and info["drive_height"] >= 8.0
        tools.add(info["tool"])
    assert tools == {"hammer", "auger"}


def test_medium_sites_place_the_machines_clear_of_everything(medium_plans):
    seeds_with = {name: 0 for name in MACHINES}
    for plan in medium_plans.values():
        for name in MACHINES:
            seeds_with[name] += any(p.asset.kind == name for p in plan.placed)
        others = [p.footprint for p in plan.placed if not p.asset.moves] + plan.reserved
        for p in plan.placed:
            if p.asset.kind in MACHINES:
                assert p.footprint.size == pytest.approx(p.asset.size, abs=1e-6)  # the size covers the geometry
                assert not any(overlaps(p.footprint, fp) for fp in others if fp is not p.footprint), (plan.seed, p.asset.kind)
                assert np.all(np.abs(p.footprint.corners()) <= plan.params.size / 2)
    assert all(n >= 2 for n in seeds_with.values()), seeds_with
