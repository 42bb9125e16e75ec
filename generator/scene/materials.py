"""Surface materials, declared once each (bpy-free): what a material looks like, by name.

A :class:`Material` names its physical description; :mod:`generator.blender.materials`
turns it into a Blender node material with seeded variation (colour jitter, roughness
jitter, pattern scale), so two sites share no exact colour. Materials used by several asset
kinds are declared here (:data:`SHARED`); a material only one kind uses is declared in that
kind's catalogue entry (:class:`generator.scene.kinds.AssetKind` ``materials``), next to
its builder. Meshes name their materials (``MeshBuilder.box(..., material="brick")``); a
name nobody declares renders as ``default``. Giving every material a new property (a
texture, a LiDAR reflectivity) is one new field of :class:`Material`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(frozen=True)
class Pattern:
    """A procedural texture layer mixed into the base colour (dirt, rust, grain, stains,
    gravel, mortar): a ``kind`` of texture (``noise``: fractal noise of ``detail`` octaves;
    ``voronoi``: cells, e.g. stones, each of its own brightness; ``courses``: the joints of
    a running bond on vertical faces, ``scale`` courses per metre of height, units ``aspect``
    times as long as a course is high, joints ``joint`` of a course thick: brick mortar,
    block joints, formwork panel joints) of ``scale`` features per metre (in the object's own
    coordinates), blending towards ``colour`` (linear RGB) with weight up to ``strength``;
    ``stretch``: its features that many times longer along the object's x, y and z (wood grain
    along a beam, dirt streaks running down a painted wall, scratches).
    Colour only: the geometry, and so every ground-truth output, is unchanged."""

    scale: float
    colour: tuple[float, float, float]
    strength: float
    kind: str = "noise"
    detail: float = 6.0
    aspect: float = 3.0
    joint: float = 0.13
    stretch: tuple[float, float, float] = (1.0, 1.0, 1.0)

    def __post_init__(self):
        if self.kind not in PATTERN_KINDS:
            raise ValueError(f"Pattern kind {self.kind!r} is unknown; choose one of {', '.join(PATTERN_KINDS)}")
        if len(self.stretch) != 3 or min(self.stretch) <= 0:
            raise ValueError(f"Pattern stretch must be three positive factors (x, y, z), got {self.stretch!r}")


PATTERN_KINDS = ("noise", "voronoi", "courses")


@dataclass(frozen=True)
class Material:
    """A named surface: base ``colour`` (linear RGB, 0-1), ``roughness`` and ``metallic``
    (Principled BSDF, 0-1), an optional :class:`Pattern` and further ``layers`` applied over
    it in order (coarse to fine), and, where the site draws them per seed instead (the
    paper's ground), ``roughness_range`` and ``specular_range``; ``planar``: the material lies on horizontal
    planes only (the ground), so its textures are evaluated in 2D, on x and y (cheaper to
    render, the same look); ``reflectivity``: the
    surface's diffuse reflectivity for a near-infrared (905 nm) laser, in [0, 1], where it is
    known to differ from what its colour suggests (None: :attr:`lidar_reflectivity` derives it
    from the colour); ``transparent``: clear glass, which a LiDAR's beam passes through
    (docs/lidar.md)."""

    name: str
    colour: tuple[float, float, float]
    roughness: float
    metallic: float = 0.0
    pattern: Pattern | None = None
    roughness_range: tuple[float, float] | None = None
    specular_range: tuple[float, float] | None = None
    layers: tuple[Pattern, ...] = ()
    reflectivity: float | None = None
    planar: bool = False
    transparent: bool = False

    def __post_init__(self):
        if self.reflectivity is not None and not 0.0 <= self.reflectivity <= 1.0:
            raise ValueError(f"material {self.name!r}: reflectivity must be in [0, 1], got {self.reflectivity!r}")

    @property
    def lidar_reflectivity(self) -> float:
        """Diffuse reflectivity at 905 nm in [0, 1] (for a LiDAR's intensity): ``reflectivity``
        where declared, else 0.05 + 0.9 x the base colour's relative luminance (Rec. 709
        weights of the linear colour): paints, soil, wood and concrete reflect the near infrared
        about as they reflect visible light, to a first approximation."""
        if self.reflectivity is not None:
            return self.reflectivity
        r, g, b = self.colour
        return 0.05 + 0.9 * (0.2126 * r + 0.7152 * g + 0.0722 * b)

    def patterns(self) -> tuple[Pattern, ...]:
        """Every texture layer, the first ``pattern`` first."""
        return ((self.pattern,) if self.pattern is not None else ()) + self.layers


def recoloured(material: Material, name: str, tint, **changes) -> Material:
    """``material`` named ``name`` with its base colour and every layer's colour multiplied by
    ``tint`` (RGB, clipped to 1) and any other fields changed by ``changes``: the same texture
    in another colour (a road of the site's soil in asphalt's colour, its tyre tracks darker)."""
    def scaled(c):
        return tuple(min(1.0, x * k) for x, k in zip(c, tint))

    pattern = None if material.pattern is None else replace(material.pattern, colour=scaled(material.pattern.colour))
    return replace(material, name=name, colour=scaled(material.colour), pattern=pattern,
                   layers=tuple(replace(p, colour=scaled(p.colour)) for p in material.layers), **changes)


# cast concrete, over its base pattern: stains and colour variation of half a metre to a few
# metres, a mottle of centimetres (pores, aggregate), and the joints of its formwork panels
# (1.2 m high, 2.4 m long)
CONCRETE_LAYERS = (Pattern(0.6, (0.26, 0.25, 0.22), 0.6, detail=4.0),
                   Pattern(12.0, (0.62, 0.61, 0.57), 0.45, detail=2.0),
                   Pattern(1 / 1.2, (0.3, 0.29, 0.27), 0.5, kind="courses", aspect=2.0, joint=0.012))

# weathering of painted steel (containers, skips, cranes, machinery): dirt streaks running
# down (stretched 8x along z) and fine scratches (stretched 12x along x)
STREAKS = Pattern(2.5, (0.07, 0.06, 0.045), 0.45, detail=3.0, stretch=(1.0, 1.0, 8.0))
SCRATCHES = Pattern(25.0, (0.55, 0.53, 0.5), 0.3, kind="voronoi", stretch=(12.0, 1.0, 1.0))
# timber: grain along the object's x (beams, boards and planks are built along x)
GRAIN = (0.3, 0.19, 0.09), 0.45  # colour of the late wood, weight

DEFAULT = "default"  # the material of faces whose material nobody declares

SHARED: tuple[Material, ...] = (
    Material(DEFAULT, (0.5, 0.5, 0.5), 0.6),
    Material("concrete", (0.45, 0.44, 0.41), 0.85, 0.0, Pattern(3.0, (0.33, 0.32, 0.3), 0.5), layers=CONCRETE_LAYERS),
    # 65 mm bricks in 75 mm courses, 215 mm long, 10 mm light mortar joints
    Material("brick", (0.42, 0.12, 0.06), 0.85, 0.0, Pattern(10.0, (0.3, 0.08, 0.05), 0.5),
             layers=(Pattern(13.3, (0.5, 0.48, 0.44), 0.75, kind="courses", aspect=3.0, joint=0.13),)),
    Material("rebar", (0.25, 0.12, 0.06), 0.7, 0.6, Pattern(20.0, (0.4, 0.18, 0.07), 0.6)),
    Material("steel_galvanized", (0.55, 0.56, 0.57), 0.45, 1.0, Pattern(12.0, (0.4, 0.4, 0.41), 0.3),
             reflectivity=0.45),  # bare metal: mostly specular, little comes back off-axis
    Material("steel_painted", (0.2, 0.2, 0.21), 0.5, 0.3, layers=(STREAKS,)),
    Material("steel_dark", (0.05, 0.05, 0.05), 0.6, 0.4, Pattern(5.0, (0.12, 0.1, 0.08), 0.4)),
    Material("wood", (0.45, 0.3, 0.15), 0.75, 0.0, Pattern(18.0, (0.32, 0.2, 0.1), 0.5),
             layers=(Pattern(40.0, GRAIN[0], GRAIN[1], detail=3.0, stretch=(15.0, 1.0, 1.0)),)),
    Material("wood_dark", (0.25, 0.16, 0.08), 0.8, 0.0, Pattern(18.0, (0.15, 0.1, 0.05), 0.5),
             layers=(Pattern(40.0, tuple(c * 0.55 for c in GRAIN[0]), GRAIN[1], detail=3.0, stretch=(15.0, 1.0, 1.0)),)),
    Material("glass", (0.02, 0.03, 0.04), 0.05, reflectivity=0.02, transparent=True),  # transmits and mirrors: next to no diffuse return
    Material("rubber", (0.02, 0.02, 0.02), 0.9, reflectivity=0.05),  # carbon black absorbs the near infrared
    Material("plastic_white", (0.8, 0.8, 0.8), 0.4),
)
