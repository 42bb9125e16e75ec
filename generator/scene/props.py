"""Smaller site objects: containers, cabins, material stacks and piles, safety equipment,
people. Sizes follow docs/scenes.md (real-world ranges, varied by seed)."""

from __future__ import annotations

import numpy as np

from ..geometry.portable_math import cos, sincos, tan, vector_norm
from .assets import Asset, Part
from .meshes import MeshBuilder, rotation_x

CONTAINER_COLOURS = ("container_blue", "container_red", "container_green", "container_grey", "container_orange", "container_white")


def _container_mesh(length: float, colour: str) -> MeshBuilder:
    """A corrugated ISO container of ``length`` (6.06 or 12.19 m), 2.44 wide, 2.59 tall,
    origin at the centre of its floor."""
    w, h = 2.44, 2.59
    b = MeshBuilder()
    b.box((length - 0.3, w - 0.1, h - 0.2), (0, 0, h / 2), material=colour)  # walls and roof
    for x in (-length / 2 + 0.075, length / 2 - 0.075):  # corner posts and end frames
        for y in (-w / 2 + 0.075, w / 2 - 0.075):
            b.box((0.15, 0.15, h), (x, y, h / 2), material=colour)
        b.box((0.15, w - 0.3, 0.15), (x, 0, 0.075), material=colour)
        b.box((0.15, w - 0.3, 0.15), (x, 0, h - 0.075), material=colour)
    for y in (-w / 2 + 0.075, w / 2 - 0.075):  # top and bottom side rails
        b.box((length - 0.3, 0.15, 0.15), (0, y, 0.075), material=colour)
        b.box((length - 0.3, 0.15, 0.15), (0, y, h - 0.075), material=colour)
    pitch = 0.28
    n = int((length - 0.5) / pitch)
    for k in range(n):  # corrugations on both long sides
        x = -(n - 1) * pitch / 2 + k * pitch
        for s in (-1, 1):
            b.box((0.14, 0.04, h - 0.35), (x, s * (w / 2 - 0.05 + 0.02), h / 2), material=colour)
    m = int((w - 0.5) / pitch)
    for k in range(n):  # roof corrugation
        x = -(n - 1) * pitch / 2 + k * pitch
        b.box((0.14, w - 0.4, 0.03), (x, 0, h - 0.1 + 0.015), material=colour)
    for k in range(m):  # corrugation on the closed end
        y = -(m - 1) * pitch / 2 + k * pitch
        b.box((0.04, 0.14, h - 0.35), (-length / 2 + 0.15 - 0.02, y, h / 2), material=colour)
    for y in (-0.7, -0.35, 0.35, 0.7):  # door locking bars
        b.cylinder(0.015, (length / 2 + 0.02, y, 0.25), (length / 2 + 0.02, y, h - 0.25), segments=6, material="steel_dark")
    return b


def container_stack(rng: np.random.Generator) -> Asset:
    """One to four containers side by side, each column stacked up to three high."""
    length = 6.06 if rng.random() < 0.6 else 12.19
    columns = int(rng.integers(1, 5))
    parts = []
    for c in range(columns):
        levels = int(rng.choice([1, 1, 2, 2, 3]))
        for lev in range(levels):
            colour = CONTAINER_COLOURS[int(rng.integers(len(CONTAINER_COLOURS)))]
            y = (c - (columns - 1) / 2) * 2.5
            parts.append(Part("Container", _container_mesh(length, colour).build(), location=(0, y, lev * 2.59)))
    return Asset("Container", parts, (length, columns * 2.5 - 0.06))


def cabin_block(rng: np.random.Generator) -> Asset:
    """Site cabins (6.0, 3.0 or 9.0 m x 2.4 x 2.7) with windows and a door, one or two
    side by side, optionally stacked two high with an outside stair."""
    length = float(rng.choice([3.0, 6.0, 6.0, 9.0]))
    count = int(rng.integers(1, 3))
    stacked = rng.random() < 0.4 and length >= 6.0
    parts = []
    w, h = 2.4, 2.7
    for c in range(count):
        for lev in range(2 if stacked else 1):
            b = MeshBuilder()
            b.box((length, w, h - 0.1), (0, 0, (h - 0.1) / 2 + 0.1), material="cabin_paint")
            b.box((length, w, 0.1), (0, 0, 0.05), material="steel_dark")
            for k in range(int(length // 3)):
                x = -length / 2 + 1.5 + 3.0 * k
                b.box((1.2, 0.04, 1.0), (x, -w / 2 - 0.02, 1.6), material="glass")
            b.box((0.9, 0.04, 2.0), (length / 2 - 0.7, -w / 2 - 0.02, 1.1), material="door_paint")
            y = (c - (count - 1) / 2) * (w + 0.1)
            parts.append(Part("Cabin", b.build(), location=(0, y, lev * h)))
    size_y = count * (w + 0.1) - 0.1
    if stacked:
        stair = MeshBuilder()
        y0 = -size_y / 2 - 1.1
        run = 3.6
        steps = 14
        for k in range(steps):
            stair.box((run / steps, 0.9, 0.05), (-length / 2 + 0.6 + (k + 0.5) * run / steps, y0 + 0.5, (k + 1) * h / steps), material="steel_galvanized")
        for s in (0.0, 1.0):  # stringers: start 0.03 m (their radius) up so the tilted end caps stay above the ground
            stair.cylinder(0.03, (-length / 2 + 0.6, y0 + s, 0.03), (-length / 2 + 0.6 + run, y0 + s, h), segments=6, material="steel_galvanized")
        stair.box((1.2, 1.0, 0.06), (-length / 2 + 0.6 + run + 0.6, y0 + 0.5, h + 0.03), material="steel_galvanized")  # landing
        stair.cylinder(0.04, (-length / 2 + 0.6 + run + 1.1, y0 + 0.1, 0), (-length / 2 + 0.6 + run + 1.1, y0 + 0.1, h), segments=6, material="steel_galvanized")
        parts.append(Part("Cabin", stair.build()))
        size_y += 2 * 1.2
    return Asset("Cabin", parts, (length + 0.2, size_y + 0.2))


def _stadium(rho: float, half_ridge: float, n_arc: int, n_line: int) -> np.ndarray:
    """Points (N, 2), counter-clockwise, at distance ``rho`` from the segment
    [-half_ridge, half_ridge] x {0}: two half circles joined by straight lines."""
    right = [(half_ridge + rho * c, rho * s) for s, c in zip(*sincos(np.linspace(-np.pi / 2, np.pi / 2, n_arc, endpoint=False)))]
    top = [(x, rho) for x in np.linspace(half_ridge, -half_ridge, n_line, endpoint=False)]
    left = [(-half_ridge + rho * c, rho * s) for s, c in zip(*sincos(np.linspace(np.pi / 2, 3 * np.pi / 2, n_arc, endpoint=False)))]
    bottom = [(x, -rho) for x in np.linspace(-half_ridge, half_ridge, n_line, endpoint=False)]
    return np.array(right + top + left + bottom)


def material_pile(rng: np.random.Generator, kind: str) -> Asset:
    """A sand or gravel pile: a cone or a ridge at a 30-35 degree angle of repose, 1-3 m
    tall, with a rough surface. Its base is exactly its footprint on the ground."""
    height = rng.uniform(1.0, 3.0)
    slope = tan(np.radians(rng.uniform(30, 35)))
    ridge = rng.uniform(1.0, 4.0) if rng.random() < 0.5 else 0.0
    radius = height / slope
    rings, n_arc, n_line = 72, 128, 32 if ridge else 0  # ~5 cm radially, ~10 cm around
    rough = 0.04 if kind == "SandPile" else 0.09
    rhos = np.linspace(radius, 0.04 * radius, rings)  # outer ring first
    verts = []
    for k, rho in enumerate(rhos):
        ring = _stadium(rho, ridge / 2, n_arc, n_line)
        z = np.full(len(ring), height - rho * slope)
        if k > 0:
            z = np.maximum(z + rng.normal(0, rough, len(ring)) * min(z[0], 1.0), 0.02)
        verts.append(np.column_stack([ring, z]))
    n = len(verts[0])
    v = np.concatenate(verts + [[[0.0, 0.0, height - rhos[-1] * slope]], [[0.0, 0.0, 0.0]]])
    top, bottom = len(v) - 2, len(v) - 1
    j = np.arange(n)
    j2 = (j + 1) % n
    quads = np.concatenate([np.stack([k * n + j, k * n + j2, (k + 1) * n + j2, (k + 1) * n + j], 1) for k in range(rings - 1)])
    last = (rings - 1) * n
    tris = np.concatenate([np.stack([last + j, last + j2, np.full(n, top)], 1),  # top cap
                           np.stack([j2, j, np.full(n, bottom)], 1)])  # base on the ground
    b = MeshBuilder().add(v, quads, tris, material="sand" if kind == "SandPile" else "gravel")
    return Asset(kind, [Part(kind, b.build())], (2 * radius + ridge + 0.2, 2 * radius + 0.2))


def brick_pallets(rng: np.random.Generator) -> Asset:
    """A row of EUR pallets (1.2 x 0.8 x 0.144) loaded with bricks or concrete blocks."""
    count = int(rng.integers(2, 7))
    blocks = rng.random() < 0.4
    unit = (0.44, 0.215, 0.215) if blocks else (0.215, 0.1025, 0.065)
    material = "concrete_block" if blocks else "brick"
    parts = []
    for c in range(count):
        b = MeshBuilder()
        for x in (-0.5, 0.0, 0.5):  # bottom boards, blocks, top deck
            b.box((0.1, 0.8, 0.022), (x, 0, 0.011), material="wood")
            for y in (-0.345, 0.0, 0.345):
                b.box((0.1, 0.1, 0.078), (x, y, 0.022 + 0.039), material="wood")
        b.box((1.2, 0.8, 0.044), (0, 0, 0.1 + 0.022), material="wood")
        nx, ny = int(1.2 // (unit[0] + 0.005)), int(0.8 // (unit[1] + 0.005))
        layers = int(round(rng.uniform(0.6, 1.0) / unit[2]))
        for lz in range(layers):
            for ix in range(nx):
                for iy in range(ny):
                    x = (ix - (nx - 1) / 2) * (unit[0] + 0.005)
                    y = (iy - (ny - 1) / 2) * (unit[1] + 0.005)
                    b.box(unit, (x, y, 0.144 + unit[2] / 2 + lz * (unit[2] + 0.001)), material=material)
        parts.append(Part("BrickPallet", b.build(), location=(0, (c - (count - 1) / 2) * 0.95, 0)))
    return Asset("BrickPallet", parts, (1.25, count * 0.95))


def pipe_stack(rng: np.random.Generator) -> Asset:
    """Concrete pipes (0.3-1.5 m, 2.5 m long) or steel pipes (6-12 m) stacked in a pyramid."""
    concrete = rng.random() < 0.5
    r = rng.uniform(0.3, 0.75) if concrete else rng.uniform(0.1, 0.3)
    wall = 0.12 * r if concrete else 0.02
    length = 2.5 if concrete else rng.uniform(6.0, 12.0)
    base = int(rng.integers(2, 5))
    b = MeshBuilder()
    if not concrete:
        for x in (-length / 3, length / 3):  # timber bearers under steel pipes
            b.box((0.15, base * 2 * r + 0.3, 0.1), (x, 0, 0.05), material="wood")
    z0 = 0.0 if concrete else 0.1
    segments = 28 if concrete else 16
    # one pipe along x at the origin, turned half a segment about its axis so that a flat
    # facet (not an edge) lies at the bottom: it rests on the ground or the bearers
    pipe = MeshBuilder().tube(r, r - wall, (-length / 2, 0, 0), (length / 2, 0, 0), segments=segments).build()
    turn = rotation_x(np.pi / segments)
    apothem = r * cos(np.pi / segments)
    for row in range(base):
        n = base - row
        for k in range(n):
            y = (k - (n - 1) / 2) * 2 * r * 1.001
            z = z0 + apothem + row * r * np.sqrt(3) * 1.001
            b.add(pipe.vertices, pipe.quads, pipe.tris, "concrete" if concrete else "steel_rust", rotation=turn, offset=(0, y, z))
    return Asset("PipeStack", [Part("PipeStack", b.build())], (length, base * 2 * r + 0.3))


def timber_stack(rng: np.random.Generator) -> Asset:
    """Sawn beams (0.1-0.2 m section, 4-6 m long) in layers on three bearers."""
    length, sec = rng.uniform(4.0, 6.0), rng.uniform(0.1, 0.2)
    per_layer, layers = int(rng.integers(4, 10)), int(rng.integers(2, 7))
    width = per_layer * (sec + 0.01)
    b = MeshBuilder()
    for x in (-length / 2 + 0.4, 0, length / 2 - 0.4):
        b.box((0.15, width + 0.2, 0.12), (x, 0, 0.06), material="wood_dark")
    for lz in range(layers):
        for k in range(per_layer):
            y = (k - (per_layer - 1) / 2) * (sec + 0.01)
            b.box((length, sec, sec), (0, y, 0.12 + sec / 2 + lz * (sec + 0.002)), material="wood")
    return Asset("TimberStack", [Part("TimberStack", b.build())], (length, width + 0.2))


def rebar_bundles(rng: np.random.Generator) -> Asset:
    """One to three bundles (0.3-0.5 m across) of bars (12-40 mm, 6-12 m long) lying on
    timber bearers."""
    length = rng.uniform(6.0, 12.0)
    count = int(rng.integers(1, 4))
    pitch = 0.6  # bundle centre to centre (0.5 m at most across, plus a gap)
    b = MeshBuilder()
    for x in (-length / 3, 0, length / 3):
        b.box((0.12, count * pitch + 0.2, 0.1), (x, 0, 0.05), material="wood_dark")
    for c in range(count):
        r = rng.uniform(0.006, 0.02)
        across = rng.uniform(0.3, 0.5)
        cols = int(np.ceil(across / (2.05 * r)))  # bars side by side: the bundle is ``across`` wide
        layers = max(1, cols // 2)  # and half as tall, lying flat
        for i in range(layers):
            for j in range(cols):
                y = (c - (count - 1) / 2) * pitch + (j - (cols - 1) / 2) * 2.05 * r
                z = 0.1 + r + i * 2.05 * r
                b.cylinder(r, (-length / 2, y, z), (length / 2, y, z), segments=6, material="rebar")
    return Asset("RebarBundle", [Part("Rebar", b.build())], (length, count * pitch + 0.2))


def fence_run(length: float) -> MeshBuilder:
    """Temporary mesh fence panels (3.5 x 2.0 m, tube frame and wire mesh) on concrete
    feet, along local +x from 0 to ``length``, centred on y = 0."""
    b = MeshBuilder()
    panels = max(1, int(round(length / 3.5)))
    pw = length / panels
    for k in range(panels + 1):
        x = k * pw
        b.box((0.7, 0.2, 0.15), (min(max(x, 0.35), length - 0.35), 0, 0.075), material="concrete")
    for k in range(panels):
        x0 = k * pw + 0.03
        x1 = x0 + pw - 0.06
        z0, z1 = 0.16, 2.0
        for x in (x0, x1):
            b.cylinder(0.02, (x, 0, z0), (x, 0, z1), segments=6, material="steel_galvanized")
        for z in (z0 + 0.02, z1 - 0.02):
            b.cylinder(0.02, (x0 + 0.021, 0, z), (x1 - 0.021, 0, z), segments=6, material="steel_galvanized")
        for x in np.arange(x0 + 0.1, x1 - 0.05, 0.1):  # 100 x 250 mm welded mesh
            b.cylinder(0.002, (x, 0, z0 + 0.041), (x, 0, z1 - 0.041), segments=4, material="steel_galvanized")
        for z in np.arange(z0 + 0.25, z1 - 0.1, 0.25):
            b.cylinder(0.002, (x0 + 0.021, 0.004, z), (x1 - 0.021, 0.004, z), segments=4, material="steel_galvanized")
    return b


def barriers(rng: np.random.Generator) -> Asset:
    """A row of 2-6 concrete jersey barriers (2-4 m long, 0.6 m base, 0.8-1.0 m tall)."""
    count, length, height = int(rng.integers(2, 7)), rng.uniform(2.0, 4.0), rng.uniform(0.8, 1.0)
    profile = [(-0.3, 0), (0.3, 0), (0.3, 0.08), (0.18, 0.33), (0.08, height), (-0.08, height), (-0.18, 0.33), (-0.3, 0.08)]
    parts = []
    for k in range(count):
        b = MeshBuilder().prism(profile, length, material="concrete_white")
        # the prism runs along y: rotate it so the row runs along x
        parts.append(Part("Barrier", b.build(), location=((k - (count - 1) / 2) * (length + 0.03), 0, 0), rotation=(0, 0, np.pi / 2)))
    return Asset("Barrier", parts, (count * (length + 0.03), 0.62))


def traffic_cones(rng: np.random.Generator) -> Asset:
    """A line of 3-8 traffic cones (0.5-1.0 m tall, orange with white bands)."""
    count, height = int(rng.integers(3, 9)), float(rng.choice([0.5, 0.75, 0.75, 1.0]))
    spacing = rng.uniform(1.0, 2.5)
    parts = []
    for k in range(count):
        b = MeshBuilder()
        b.box((0.38 * height / 0.75, 0.38 * height / 0.75, 0.03), (0, 0, 0.015), material="plastic_orange")
        r0, r1 = 0.15 * height / 0.75, 0.03
        zs = [0.03, 0.35 * height, 0.5 * height, 0.6 * height, 0.72 * height, height]
        mats = ["plastic_orange", "reflective_white", "plastic_orange", "reflective_white", "plastic_orange"]
        for a in range(5):
            ra = r0 + (r1 - r0) * (zs[a] - 0.03) / (height - 0.03)
            rb = r0 + (r1 - r0) * (zs[a + 1] - 0.03) / (height - 0.03)
            b.cone(ra, rb, (0, 0, zs[a]), (0, 0, zs[a + 1]), segments=16, material=mats[a])
        parts.append(Part("TrafficCone", b.build(), location=((k - (count - 1) / 2) * spacing, 0, 0)))
    return Asset("TrafficCone", parts, (count * spacing, 0.6))


def portable_toilets(rng: np.random.Generator) -> Asset:
    """One to four portable toilets (1.1 x 1.2 x 2.3 m) side by side."""
    count = int(rng.integers(1, 5))
    parts = []
    for k in range(count):
        b = MeshBuilder()
        b.box((1.1, 1.2, 2.2), (0, 0, 1.1), material="plastic_toilet")
        b.box((1.15, 1.2, 0.1), (0, 0, 2.25), material="plastic_white")  # roof: no wider than the 1.2 m body
        b.box((0.04, 0.8, 1.9), (0.57, 0, 1.0), material="plastic_toilet_door")
        b.cylinder(0.04, (-0.4, 0.4, 2.3), (-0.4, 0.4, 2.6), segments=8, material="plastic_white")
        parts.append(Part("PortableToilet", b.build(), location=(0, (k - (count - 1) / 2) * 1.25, 0)))
    return Asset("PortableToilet", parts, (1.3, count * 1.25))


def skip(rng: np.random.Generator) -> Asset:
    """An open skip (3.7 x 1.8 x 1.2 m) with sloped ends, sometimes partly filled."""
    b = MeshBuilder()
    length, width, height, t = 3.7, 1.8, 1.2, 0.05
    b.box((length - 1.0, width, t), (0, 0, t / 2), material="skip_paint")
    for s in (-1, 1):
        b.prism([(-(length - 1.0) / 2, 0), ((length - 1.0) / 2, 0), (length / 2, height), (-length / 2, height)], t,
                offset=(0, s * (width / 2 - t / 2), 0), material="skip_paint")
        # sloped end wall: a plate from the floor's end up to the rim
        bottom, top = np.array([s * (length - 1.0) / 2, 0, 0]), np.array([s * length / 2, 0, height])
        ex = (top - bottom) / vector_norm(top - bottom)
        ey = np.array([0.0, 1.0, 0.0])
        ez = np.cross(ex, ey)
        rot = np.column_stack([ex, ey, ez])
        lift = np.array([0.0, 0.0, abs(ez[2]) * t / 2 + 1e-3])  # the plate's lower edge stays on the ground
        b.box((vector_norm(top - bottom), width - 2 * t - 0.01, t), (bottom + top) / 2 + lift, rotation=rot, material="skip_paint")
    if rng.random() < 0.6:
        fill = rng.uniform(0.2, 0.8)
        b.box((length - 1.2, width - 2 * t - 0.05, fill), (0, 0, t + fill / 2 + 0.001), material="rubble")
    return Asset("Skip", [Part("Skip", b.build())], (length + 0.1, width + 0.1))


def generator_set(rng: np.random.Generator) -> Asset:
    """A site generator (2-4 m x 1 m x 1.5 m) on a base frame, with an exhaust stack."""
    length = rng.uniform(2.0, 4.0)
    b = MeshBuilder()
    b.box((length, 1.1, 0.15), (0, 0, 0.075), material="steel_dark")
    b.box((length - 0.1, 1.0, 1.35), (0, 0, 0.15 + 0.675), material="generator_paint")
    b.cylinder(0.06, (length / 2 - 0.4, 0.2, 1.5), (length / 2 - 0.4, 0.2, 1.9), segments=8, material="steel_dark")
    b.box((0.03, 0.5, 0.4), (-length / 2 + 0.03, 0, 0.9), material="steel_dark")  # control panel
    return Asset("Generator", [Part("Generator", b.build())], (length + 0.1, 1.2))


def workers(rng: np.random.Generator) -> Asset:
    """One to four workers (1.6-1.9 m) in hi-vis vests and hard hats, standing."""
    count = int(rng.integers(1, 5))
    parts = []
    for k in range(count):
        h = rng.uniform(1.6, 1.9)
        s = h / 1.75
        b = MeshBuilder()
        for y in (-0.1, 0.1):
            b.box((0.16 * s, 0.14 * s, 0.82 * s), (0, y * s, 0.41 * s), material="work_trousers")
            b.box((0.28 * s, 0.12 * s, 0.08 * s), (0.05 * s, y * s, 0.04 * s), material="rubber")  # boots
        b.box((0.26 * s, 0.42 * s, 0.58 * s), (0, 0, 0.82 * s + 0.29 * s), material="hivis")
        for y in (-0.26, 0.26):
            b.box((0.12 * s, 0.1 * s, 0.6 * s), (0, y * s, 0.82 * s + 0.26 * s), material="hivis")
        b.box((0.1 * s, 0.1 * s, 0.08 * s), (0, 0, 1.44 * s), material="skin")  # neck
        b.cone(0.1 * s, 0.09 * s, (0, 0, 1.48 * s), (0, 0, 1.68 * s), segments=10, material="skin")
        b.cone(0.14 * s, 0.08 * s, (0, 0, 1.64 * s), (0, 0, 1.75 * s), segments=12, material="hard_hat")
        parts.append(Part("Worker", b.build(), location=(0, (k - (count - 1) / 2) * 0.8, 0), rotation=(0, 0, rng.uniform(-0.8, 0.8))))
    return Asset("Worker", parts, (0.8, count * 0.8))
