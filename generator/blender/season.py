"""The season of a site in its materials (generator/scene/weather.py ``season``,
``snow_cover``): colour only, never the geometry, so every ground-truth output is the same
in every season.

- Leaves and grass take the season's tint (:data:`TINTS`: a factor on their base colour):
  fresh in spring, dry grass in summer, yellow and orange leaves in autumn, withered ones
  in winter (hedges, evergreen, change a third as much).
- Snow (the ``snow`` season) lies on every upward face of every material: faces within
  about 35 degrees of level, under a patchy mask (fractal noise about 2 m across, above a
  threshold set by ``snow_cover``), turning white and a little smoother.
"""

from __future__ import annotations

import bpy

from .materials import material_name

# factor on the base colour of leaves and of grass, per season
TINTS = {
    "spring": {"leaves": (1.15, 1.3, 0.9), "grass": (1.1, 1.35, 0.9)},
    "summer": {"leaves": (1.0, 1.0, 1.0), "grass": (1.35, 1.2, 0.8)},
    "autumn": {"leaves": (3.4, 1.8, 0.6), "grass": (1.7, 1.3, 0.75)},
    "winter": {"leaves": (2.2, 1.2, 0.9), "grass": (1.9, 1.5, 1.0)},
    "snow": {"leaves": (2.2, 1.2, 0.9), "grass": (1.9, 1.5, 1.0)},
}
LEAVES = ("foliage", "foliage_light", "foliage_dark")
HEDGES = ("hedge",)
GRASS = ("grass",)
SNOW_COLOUR = (0.78, 0.8, 0.84, 1.0)  # linear RGB: old snow, a little grey and blue
SNOW_ROUGHNESS = 0.55
SNOW_LABEL = "snow"  # the label of a material's snow mask node


def apply_season(season: str, snow_cover: float) -> None:
    """Tint the open file's leaves and grass for ``season`` and lay ``snow_cover`` of snow
    on every material (module docstring)."""
    tint = TINTS[season]
    for keys, factor, weight in ((LEAVES, tint["leaves"], 1.0), (HEDGES, tint["leaves"], 1 / 3), (GRASS, tint["grass"], 1.0)):
        for key in keys:
            material = bpy.data.materials.get(material_name(key))
            if material is not None:
                _multiply_base(material, tuple(1.0 + (f - 1.0) * weight for f in factor))
    if snow_cover > 0:
        for material in bpy.data.materials:
            if material.node_tree is not None and "Principled BSDF" in material.node_tree.nodes:
                _snow(material, snow_cover)


def _base_source(nodes, links, bsdf):
    """The Base Color socket's input: its link's source, or a colour node holding its value."""
    base = bsdf.inputs["Base Color"]
    if base.links:
        return base.links[0].from_socket
    rgb = nodes.new("ShaderNodeRGB")
    rgb.outputs["Color"].default_value = tuple(base.default_value)
    return rgb.outputs["Color"]


def _multiply_base(material, factor) -> None:
    nodes, links = material.node_tree.nodes, material.node_tree.links
    bsdf = nodes["Principled BSDF"]
    mix = nodes.new("ShaderNodeMix")
    mix.data_type, mix.blend_type = "RGBA", "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    links.new(_base_source(nodes, links, bsdf), mix.inputs["A"])
    mix.inputs["B"].default_value = (*factor, 1.0)
    links.new(mix.outputs["Result"], bsdf.inputs["Base Color"])


def _snow(material, cover: float) -> None:
    nodes, links = material.node_tree.nodes, material.node_tree.links
    bsdf = nodes["Principled BSDF"]
    geometry, up = nodes.new("ShaderNodeNewGeometry"), nodes.new("ShaderNodeSeparateXYZ")
    links.new(geometry.outputs["Normal"], up.inputs["Vector"])
    level = nodes.new("ShaderNodeMapRange")  # 0 on faces steeper than ~45 degrees, 1 within ~25 of level
    level.inputs["From Min"].default_value, level.inputs["From Max"].default_value = 0.7, 0.9
    links.new(up.outputs["Z"], level.inputs["Value"])
    coords, noise = nodes.new("ShaderNodeTexCoord"), nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 0.5
    noise.inputs["Detail"].default_value = 6.0
    links.new(coords.outputs["Object"], noise.inputs["Vector"])
    patch = nodes.new("ShaderNodeMapRange")
    patch.label = SNOW_LABEL
    start = 0.72 - 0.45 * cover  # fractal noise is about 0.5 +- 0.2: cover 0.5 covers about half
    patch.inputs["From Min"].default_value, patch.inputs["From Max"].default_value = start, start + 0.04
    links.new(noise.outputs["Fac"], patch.inputs["Value"])
    factor = nodes.new("ShaderNodeMath")
    factor.operation = "MULTIPLY"
    links.new(level.outputs["Result"], factor.inputs[0])
    links.new(patch.outputs["Result"], factor.inputs[1])
    colour = nodes.new("ShaderNodeMix")
    colour.data_type = "RGBA"
    links.new(factor.outputs["Value"], colour.inputs["Factor"])
    links.new(_base_source(nodes, links, bsdf), colour.inputs["A"])
    colour.inputs["B"].default_value = SNOW_COLOUR
    links.new(colour.outputs["Result"], bsdf.inputs["Base Color"])
    rough = bsdf.inputs["Roughness"]
    smooth = nodes.new("ShaderNodeMix")
    links.new(factor.outputs["Value"], smooth.inputs["Factor"])
    if rough.links:
        links.new(rough.links[0].from_socket, smooth.inputs["A"])
    else:
        smooth.inputs["A"].default_value = float(rough.default_value)
    smooth.inputs["B"].default_value = SNOW_ROUGHNESS
    links.new(smooth.outputs["Result"], rough)
