"""The semantic taxonomy of generated construction sites (stable ids, never reordered).

Object names carry their class (``Crane.003``), so a saved site reloads with the same
labels; the site also stores this table in the scene's ``buildee_labels`` property, which
makes the Simulator use these ids (see docs/scenes.md). The first release's classes
and those added since (:data:`FIXED`, appended in the order they came) keep their ids for
good; a class that a catalogue kind names and that is not
among them (:class:`generator.scene.kinds.AssetKind` ``classes``) is appended after them,
the new ones sorted by name, with the colour its kind declares.
"""

from __future__ import annotations

from .kinds import all_kinds

FIXED: tuple[tuple[str, tuple[int, int, int]], ...] = (  # (class, RGB 0-255 for maps and figures), id = position
    ("Ground", (120, 110, 95)),          # 0  terrain of the site
    ("Building", (170, 170, 170)),       # 1  concrete structure under construction: slabs, columns, core walls
    ("Rebar", (150, 60, 40)),            # 2  reinforcement: starter bars on slabs, rebar bundles on the ground
    ("Formwork", (220, 190, 60)),        # 3  formwork panels
    ("Scaffolding", (90, 140, 200)),     # 4  tubes, planks, braces
    ("Crane", (250, 200, 0)),            # 5  tower crane: mast, jib, counter-jib, weights, cab, trolley, hook
    ("Container", (40, 110, 170)),       # 6  shipping containers (20 and 40 ft), stacked
    ("Cabin", (240, 240, 240)),          # 7  site offices / welfare cabins, stairs
    ("Truck", (230, 90, 30)),            # 8  dump and mixer trucks, wheels included
    ("Excavator", (255, 160, 0)),        # 9  tracks, body, boom, arm, bucket
    ("SandPile", (225, 200, 140)),       # 10
    ("GravelPile", (140, 140, 130)),     # 11
    ("BrickPallet", (180, 70, 50)),      # 12 pallets of bricks or blocks
    ("PipeStack", (100, 100, 110)),      # 13 concrete or steel pipes
    ("TimberStack", (160, 110, 60)),     # 14 beams on bearers
    ("Fence", (200, 200, 210)),          # 15 temporary mesh fence panels and their feet
    ("Barrier", (230, 230, 220)),        # 16 concrete jersey barriers
    ("TrafficCone", (255, 110, 0)),      # 17
    ("PortableToilet", (30, 150, 80)),   # 18
    ("Skip", (200, 160, 0)),             # 19 open skips / dumpsters
    ("Generator", (60, 160, 60)),        # 20 site power generators
    ("Worker", (255, 90, 200)),          # 21 people in hi-vis vests and hard hats
    # added with the site kinds and surroundings (issue #39); appended, never reordered
    ("MobileCrane", (255, 235, 120)),    # 22 truck-mounted telescopic cranes: carrier, outriggers, boom, hook
    ("PumpTruck", (120, 60, 160)),       # 23 truck-mounted concrete pumps: carrier, outriggers, placing boom
    ("Roller", (250, 140, 120)),         # 24 single-drum soil compactors
    ("Loader", (200, 120, 0)),           # 25 wheel loaders: articulated body, arms, bucket
    ("PileDriver", (130, 30, 90)),       # 26 piling rigs: tracks, body, leader mast, hammer or auger
    ("Car", (0, 150, 200)),              # 27 parked cars beyond the fence
    ("StreetLight", (250, 250, 120)),    # 28 street-light columns and lanterns
    ("Vegetation", (60, 180, 60)),       # 29 trees and hedges
    ("Neighbour", (120, 90, 150)),       # 30 finished buildings beyond the fence: walls, windows, roofs
)


def added_classes() -> dict[str, tuple[int, int, int]]:
    """The catalogue's classes beyond :data:`FIXED`, sorted by name, with their colours."""
    fixed = {name for name, _ in FIXED}
    added: dict[str, tuple[int, int, int]] = {}
    for k in all_kinds():
        for name in k.classes:
            if name in fixed or name in added:
                continue
            if k.colour is None:
                raise ValueError(f"asset kind {k.name!r} adds the class {name!r}: give the entry a colour=(r, g, b)")
            added[name] = tuple(k.colour)
    return dict(sorted(added.items()))


CLASSES: tuple[str, ...] = tuple(name for name, _ in FIXED) + tuple(added_classes())

CLASS_ID: dict[str, int] = {name: i for i, name in enumerate(CLASSES)}

# Colours (RGB 0-255) for maps and figures, one per class.
CLASS_COLORS: dict[str, tuple[int, int, int]] = dict(FIXED) | added_classes()
