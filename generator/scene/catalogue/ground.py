"""The site's ground (added by the Blender build to every site; not placed by the plan): one
flat top surface wider than the site, and what it is made of, chosen per seed
(:func:`choose_ground`): the site's surface (one of :data:`SURFACES`), the surface of its haul
road and gate access (:data:`ROADS`), with tyre tracks along them, and grass and weeds beyond
the fence. Colour only: the ground's geometry, and so every ground-truth output, is the same
whatever it is made of (docs/scenes.md, "What the ground is made of")."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ...geometry.seeding import stream
from ..assets import Part
from ..kinds import AssetKind, register
from ..ground_layout import GroundRegions, ground_mesh
from ..materials import SHARED, Material, Pattern, recoloured
from ..meshes import MeshBuilder
from ..relief import Relief

GROUND_MARGIN = 20.0  # metres of ground beyond the site's edge on every side (seen from the spawn volume)


def surface_material(surface: str) -> str:
    """The material name of the site surface ``surface``."""
    return f"ground-{surface}"


# The contrast structure every surface shares (tuned on SIFT and the share of flat patches,
# benchmarks/surfaces.py): (features per metre, the layer's colour as a multiple of the base
# colour, strength, kind): areas tens of metres across, light patches and a dark mottle of a
# metre or two, clods of decimetres, grains of centimetres.
SOIL_STRUCTURE = ((0.5, 2.5, 0.8, "noise"), (0.7, 0.4, 0.6, "voronoi"), (1.5, 0.35, 0.85, "voronoi"),
                  (0.9, 0.45, 0.6, "noise"), (5.0, 0.57, 0.6, "voronoi"), (25.0, 1.8, 0.5, "voronoi"))


def soil(name: str, colour: tuple[float, float, float], extra: tuple[Pattern, ...] = (),
         roughness_range=(0.5, 1.0), specular_range=(0.05, 0.2)) -> Material:
    """A ground surface of base ``colour`` (linear RGB) with the shared contrast structure, damp
    and dry areas about 25 m across (half the base's brightness), and ``extra`` layers on top;
    roughness and specular drawn per seed as the paper's ground."""
    scaled = [Pattern(scale, tuple(min(1.0, c * k) for c in colour), strength, kind=kind,
                      detail=4.0 if kind == "noise" and scale < 0.6 else 3.0) for scale, k, strength, kind in SOIL_STRUCTURE]
    return Material(surface_material(name), colour, 0.9, 0.0, Pattern(0.04, tuple(0.52 * c for c in colour), 0.6, detail=4.0),
                    roughness_range=roughness_range, specular_range=specular_range, layers=tuple(scaled) + extra,
                    planar=True)


# name: (weight per seed, material)
SURFACES: dict[str, tuple[float, Material]] = {
    "compacted-soil": (0.25, soil("compacted-soil", (0.23, 0.18, 0.12))),
    "mud": (0.2, soil("mud", (0.15, 0.115, 0.08), (Pattern(2.5, (0.36, 0.28, 0.2), 0.65, kind="voronoi"),  # drying crust
                                                    Pattern(12.0, (0.3, 0.23, 0.16), 0.6, kind="voronoi"),  # clods
                                                    Pattern(4.0, (0.05, 0.04, 0.03), 0.5, kind="voronoi")),  # wet hollows
                      roughness_range=(0.45, 0.8), specular_range=(0.2, 0.4))),
    # crushed-stone hardstanding: grey, with stones of several centimetres
    "gravel": (0.2, soil("gravel", (0.16, 0.155, 0.145))),
    "dry-dust": (0.2, soil("dry-dust", (0.3, 0.25, 0.18), roughness_range=(0.8, 1.0), specular_range=(0.05, 0.2))),
    "clay": (0.15, soil("clay", (0.3, 0.14, 0.06))),
}
# the haul road's and gate access's surface: name: (weight per seed, the material whose colour,
# roughness and LiDAR reflectivity it takes; None: the site's surface itself, rutted by the
# traffic). A road is the site surface's texture recoloured (:func:`road_material`).
ROADS: dict[str, tuple[float, str | None]] = {
    "rutted": (0.4, None),
    "gravel": (0.2, surface_material("gravel")),
    "asphalt": (0.2, "asphalt"),
    "concrete": (0.2, "concrete"),
}
ASPHALT = Material("asphalt", (0.05, 0.05, 0.05), 0.8, reflectivity=0.08)
GRASS = Material("grass", (0.08, 0.12, 0.03), 0.8, 0.0, Pattern(0.3, (0.16, 0.15, 0.05), 0.6, detail=4.0),
                 layers=(Pattern(3.0, (0.04, 0.07, 0.02), 0.6, kind="voronoi"),),
                 reflectivity=0.5, planar=True)  # leaves reflect the near infrared strongly
SPOIL = soil("spoil", (0.19, 0.13, 0.075), (Pattern(8.0, (0.16, 0.12, 0.07), 0.5, kind="voronoi"),))  # dug subsoil, lumpy
PAVED = ("asphalt", "concrete")  # roads that do not rut
RUT_DEPTH_M = 0.04  # tyre tracks on an unpaved road are sunk this deep
TRACKS_SHADE = 0.55  # tyre tracks: the road's colours times this, and its roughness times 0.75 (compacted)


def road_material(surface: str, road: str) -> str:
    """The material name of the road ``road`` on the site surface ``surface``."""
    return surface_material(surface) if ROADS[road][1] is None else f"{surface_material(surface)}-{road}"


def tracks_material(surface: str, road: str) -> str:
    """The material name of the tyre tracks on that road."""
    return f"{road_material(surface, road)}-tracks"


def _derived() -> tuple[Material, ...]:
    """Every road and track material: the surface's texture recoloured."""
    known = {m.name: m for m in SHARED} | {m.name: m for _, m in SURFACES.values()} | {ASPHALT.name: ASPHALT}
    out = []
    for surface, (_, soil_) in SURFACES.items():
        for road, (_, paved_name) in ROADS.items():
            road_ = soil_
            if paved_name is not None:
                paved = known[paved_name]
                tint = tuple(p / c for p, c in zip(paved.colour, soil_.colour))
                road_ = recoloured(soil_, road_material(surface, road), tint, roughness_range=paved.roughness_range,
                                   roughness=paved.roughness, reflectivity=paved.reflectivity)
                out.append(road_)
            rough = road_.roughness_range
            out.append(recoloured(road_, tracks_material(surface, road), (TRACKS_SHADE,) * 3, roughness=road_.roughness * 0.75,
                                  roughness_range=None if rough is None else (rough[0] * 0.75, rough[1] * 0.75)))
    return tuple(out)


@dataclass(frozen=True)
class GroundSurface:
    """What a site's ground is made of: ``surface`` (a :data:`SURFACES` name) inside the fence,
    ``road`` (a :data:`ROADS` name) on the haul road and the gate access, tyre tracks along
    them, and grass and weeds (:data:`GRASS`) beyond the fence."""

    surface: str
    road: str

    @property
    def material(self) -> str:
        """The material of the ground's faces (the surface's)."""
        return surface_material(self.surface)

    @property
    def road_material(self) -> str:
        """The material of the road's faces."""
        return road_material(self.surface, self.road)

    @property
    def tracks_material(self) -> str:
        """The material of the tyre tracks' faces."""
        return tracks_material(self.surface, self.road)

    @property
    def rut_depth(self) -> float:
        """Metres the tyre tracks are sunk (0 on a paved road)."""
        return 0.0 if self.road in PAVED else RUT_DEPTH_M

    def summary(self) -> dict:
        """site.json's ``ground``: surface and road kinds."""
        return asdict(self)


def split_margin(ground: Part, half: float) -> tuple[Part, Part]:
    """The ground part of a site of half-side ``half`` as (the site's ground, the ground
    beyond the site's edge): the faces whose centre lies outside the square go to a second
    part flagged as scenery (in the images and their ground truth, no surface points: the
    streets and neighbours beyond the fence stand on it)."""
    m = ground.mesh
    faces = [m.quads, m.tris]
    centres = np.concatenate([m.vertices[f].mean(axis=1) for f in faces if len(f)])
    beyond = np.max(np.abs(centres[:, :2]), axis=1) > half + 1e-9
    return Part("Ground", m.faces_where(~beyond)), Part("Ground", m.faces_where(beyond), scenery=True)


def wet_materials(ground: Part) -> list[str]:
    """The materials of the ground part ``ground`` that rain wets (all but the grass's)."""
    return [m for m in ground.mesh.materials if m != GRASS.name]


def check_surface(name: str | None) -> str | None:
    """``name`` if it names a ground surface (or is None: drawn per seed); ValueError otherwise."""
    if name is not None and name not in SURFACES:
        raise ValueError(f"unknown ground surface {name!r}; choose one of {', '.join(SURFACES)}")
    return name


def choose_ground(seed: int, surface: str | None = None) -> GroundSurface:
    """The ground of the site of ``seed``: its surface (``surface``, or drawn by weight) and its
    road's, from the seed's own ``ground`` stream (no other stream moves)."""
    check_surface(surface)
    rng = stream(seed, "ground")
    names, roads = list(SURFACES), list(ROADS)
    drawn = names[int(rng.choice(len(names), p=[SURFACES[n][0] for n in names]))]
    road = roads[int(rng.choice(len(roads), p=[ROADS[n][0] for n in roads]))]
    return GroundSurface(surface or drawn, road)


def ground_part(size: float, ground: GroundSurface | None = None, road_half: float | None = None,
                corner: float = 8.0, width: float = 7.0, gate: tuple[float, float] = (-4.0, 4.0),
                relief: Relief | None = None) -> Part:
    """The ground: a top surface (normals up), ``GROUND_MARGIN`` metres wider than the site of
    side ``size`` on every side, made of ``ground`` (default: compacted soil with a rutted
    road). With the road loop's centre line half-side ``road_half`` (its corner radius
    ``corner``, its ``width``, the gate access's x range ``gate``), its faces follow the
    regions of :mod:`generator.scene.ground_layout` (road with ruts, tyre tracks, site
    surface, grass beyond the fence) and ``relief``'s digs and terrain
    (:mod:`generator.scene.relief`); without, it is two triangles of the site's surface at
    z = 0. It has no underside and no sides below grade: nothing a camera above it could see
    (docs/scenes.md)."""
    ground = ground or GroundSurface("compacted-soil", "rutted")
    if road_half is None:
        h = size / 2 + GROUND_MARGIN
        verts = [(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)]  # counter-clockwise seen from above
        return Part("Ground", MeshBuilder().add(verts, quads=[(0, 1, 2, 3)], material=ground.material).build())
    relief = relief or Relief()
    regions = GroundRegions(size / 2, road_half, corner, width, gate, GROUND_MARGIN, ground.material,
                            ground.road_material, ground.tracks_material, GRASS.name, SPOIL.name, ground.rut_depth,
                            tuple(relief.digs), relief.terrain)
    return Part("Ground", ground_mesh(regions))


register(AssetKind(
    name="Ground", classes=("Ground",), build=ground_part, order=0,
    materials=tuple(m for _, m in SURFACES.values()) + (ASPHALT, GRASS, SPOIL) + _derived(),
    shared_streams=True,
))
