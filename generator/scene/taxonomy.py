"""The fixed semantic taxonomy of generated construction sites (stable ids, never reordered).

Object names carry their class (``Crane.003``), so a saved site reloads with the same
labels; the site also stores this table in the scene's ``buildee_labels`` property, which
makes the Simulator use these ids (see docs/scenes.md). New classes are only ever appended.
"""

from __future__ import annotations

CLASSES: tuple[str, ...] = (
    "Ground",          # 0  terrain of the site
    "Building",        # 1  concrete structure under construction: slabs, columns, core walls
    "Rebar",           # 2  reinforcement: starter bars on slabs, rebar bundles on the ground
    "Formwork",        # 3  formwork panels
    "Scaffolding",     # 4  tubes, planks, braces
    "Crane",           # 5  tower crane: mast, jib, counter-jib, weights, cab, trolley, hook
    "Container",       # 6  shipping containers (20 and 40 ft), stacked
    "Cabin",           # 7  site offices / welfare cabins, stairs
    "Truck",           # 8  dump and mixer trucks, wheels included
    "Excavator",       # 9  tracks, body, boom, arm, bucket
    "SandPile",        # 10
    "GravelPile",      # 11
    "BrickPallet",     # 12 pallets of bricks or blocks
    "PipeStack",       # 13 concrete or steel pipes
    "TimberStack",     # 14 beams on bearers
    "Fence",           # 15 temporary mesh fence panels and their feet
    "Barrier",         # 16 concrete jersey barriers
    "TrafficCone",     # 17
    "PortableToilet",  # 18
    "Skip",            # 19 open skips / dumpsters
    "Generator",       # 20 site power generators
    "Worker",          # 21 people in hi-vis vests and hard hats
)

CLASS_ID: dict[str, int] = {name: i for i, name in enumerate(CLASSES)}

# Colours (RGB 0-255) for maps and figures, one per class.
CLASS_COLORS: dict[str, tuple[int, int, int]] = {
    "Ground": (120, 110, 95), "Building": (170, 170, 170), "Rebar": (150, 60, 40),
    "Formwork": (220, 190, 60), "Scaffolding": (90, 140, 200), "Crane": (250, 200, 0),
    "Container": (40, 110, 170), "Cabin": (240, 240, 240), "Truck": (230, 90, 30),
    "Excavator": (255, 160, 0), "SandPile": (225, 200, 140), "GravelPile": (140, 140, 130),
    "BrickPallet": (180, 70, 50), "PipeStack": (100, 100, 110), "TimberStack": (160, 110, 60),
    "Fence": (200, 200, 210), "Barrier": (230, 230, 220), "TrafficCone": (255, 110, 0),
    "PortableToilet": (30, 150, 80), "Skip": (200, 160, 0), "Generator": (60, 160, 60),
    "Worker": (255, 90, 200),
}
