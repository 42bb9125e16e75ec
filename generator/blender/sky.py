"""The sun, the sky and the weather of a site in Blender, from its bpy-free
:class:`generator.scene.weather.Weather` (chosen per seed: generator/scene/weather.py).

- The sun: a sun lamp at the weather's elevation and azimuth, strength and angular size.
- The sky (the world shader): Hosek-Wilkie for ``clear`` and ``hazy``; the same with
  procedural clouds (fractal noise on the plane 1 km up, seen along each view direction) for
  ``partly-cloudy``; the CIE overcast sky with faint cloud texture for ``overcast``.
- Wet ground: the ground material darkens and turns glossy by ``wetness``, and puddles (low
  fractal noise over the ground's level faces, about 10 m across) are mirrors through which
  the soil shows, a third as bright.
- Fog: recorded in the scene (:data:`FOG_PROPERTY`, the extinction per metre and the fog's
  colour) for the renderer, which mixes each pixel with the fog's colour by the
  transmittance exp(-extinction x distance) along its ray (generator/blender/render.py).
- Exposure: the view's exposure compensation (Blender's Film > Color Management exposure).

Colour only: no object is added or moved, so every ground-truth output is the same whatever
the weather."""

from __future__ import annotations

import json
import math

import bpy
import numpy as np

from ..geometry.portable_math import sin, sincos
from ..scene.weather import Weather

FOG_PROPERTY = "buildee_fog"  # scene property: JSON {"extinction_per_m": float, "colour": [r, g, b]}
MIST_DEPTH = 100_000.0  # metres: the Mist pass's linear range (the sky reads as this far)
PUDDLES = "puddles"  # the label of wet ground's puddle mask node
OVERCAST_COLOUR = (0.105, 0.11, 0.12)  # the overcast zenith's radiance before the sky strength (linear RGB)


def build_sky(weather: Weather, ground=()) -> None:
    """Sun lamp, world shader, exposure and fog of ``weather`` in the open scene; wet ground
    on the materials ``ground`` (the site's ground's but the grass: surface, road, tracks, digs; each once) when
    the weather is wet."""
    scene = bpy.context.scene
    elevation, azimuth = math.radians(weather.sun_elevation_deg), math.radians(weather.sun_azimuth_deg)
    sun_data = bpy.data.lights.new("Sun", "SUN")
    sun_data.energy = weather.sun_strength
    sun_data.angle = math.radians(weather.sun_angle_deg)
    sun = bpy.data.objects.new("Sun", sun_data)
    scene.collection.objects.link(sun)
    # a sun light shines along its -Z: point -Z from the sun towards the ground
    sun.rotation_euler = (math.pi / 2 - elevation, 0.0, azimuth + math.pi / 2)
    world = bpy.data.worlds.new("Sky")
    scene.world = world
    if world.node_tree is None:
        world.use_nodes = True
    nodes, links = world.node_tree.nodes, world.node_tree.links
    bg = nodes.get("Background") or nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = weather.sky_strength
    if weather.sky == "overcast":
        colour = _overcast(nodes, links)
    else:
        sky = nodes.new("ShaderNodeTexSky")
        sky.sky_type = "HOSEK_WILKIE"
        sky.turbidity = weather.turbidity
        sky.ground_albedo = 0.3
        (se, ce), (sa, ca) = sincos(elevation), sincos(azimuth)
        sky.sun_direction = (ce * ca, ce * sa, se)
        colour = sky.outputs["Color"]
        if weather.cloud_cover > 0:
            colour = _clouds(nodes, links, colour, weather.cloud_cover)
    links.new(colour, bg.inputs["Color"])
    scene.view_settings.exposure = weather.exposure_ev
    if weather.fog_visibility_m is not None:
        # the fog glows as the overcast sky does 40 degrees up (so the sky fades into it)
        glow = weather.sky_strength * (1 + 2 * float(sin(math.radians(40.0)))) / 3
        scene[FOG_PROPERTY] = json.dumps({"extinction_per_m": weather.fog_extinction_per_m,
                                          "colour": [c * glow for c in OVERCAST_COLOUR]})
    if weather.wetness > 0:
        for material in dict.fromkeys(ground):
            wet_ground(material, weather.wetness)


def fog_of_scene(scene) -> dict | None:
    """The open scene's fog ({"extinction_per_m", "colour"}), or None without fog."""
    value = scene.get(FOG_PROPERTY)
    return None if value is None else json.loads(value)


def _math(nodes, links, operation: str, a, b=None):
    """A Math node ``operation`` of ``a`` and ``b`` (sockets or numbers); its output socket."""
    node = nodes.new("ShaderNodeMath")
    node.operation = operation
    for socket, value in zip(node.inputs, (a, b)):
        if value is None:
            continue
        if isinstance(value, (int, float)):
            socket.default_value = float(value)
        else:
            links.new(value, socket)
    return node.outputs[0]


def _view_direction(nodes, links):
    """(x, y, z) output sockets of the world's view direction (unit vector, z up)."""
    coords = nodes.new("ShaderNodeTexCoord")
    split = nodes.new("ShaderNodeSeparateXYZ")
    links.new(coords.outputs["Generated"], split.inputs[0])
    return split.outputs["X"], split.outputs["Y"], split.outputs["Z"]


def _cloud_noise(nodes, links, scale: float):
    """Fractal noise on the cloud plane seen along each view direction (the direction divided
    by its height: the plane at unit height), and the view direction's height z."""
    x, y, z = _view_direction(nodes, links)
    up = _math(nodes, links, "MAXIMUM", z, 0.03)
    plane = nodes.new("ShaderNodeCombineXYZ")
    links.new(_math(nodes, links, "DIVIDE", x, up), plane.inputs["X"])
    links.new(_math(nodes, links, "DIVIDE", y, up), plane.inputs["Y"])
    noise = nodes.new("ShaderNodeTexNoise")
    noise.noise_dimensions = "2D"
    noise.inputs["Scale"].default_value = scale
    noise.inputs["Detail"].default_value = 4.0
    noise.inputs["Roughness"].default_value = 0.55
    links.new(plane.outputs["Vector"], noise.inputs["Vector"])
    return noise.outputs["Fac"], z


def _clouds(nodes, links, sky_colour, cover: float):
    """``sky_colour`` with clouds over about ``cover`` of the sky above the horizon."""
    fac, z = _cloud_noise(nodes, links, 1.6)
    threshold = 0.5 + (0.5 - cover) * 0.3  # the noise's values spread about 0.5
    mask = nodes.new("ShaderNodeMapRange")
    mask.inputs["From Min"].default_value, mask.inputs["From Max"].default_value = threshold - 0.04, threshold + 0.12
    links.new(fac, mask.inputs["Value"])
    horizon = nodes.new("ShaderNodeMapRange")  # clouds fade into the haze at the horizon
    horizon.inputs["From Min"].default_value, horizon.inputs["From Max"].default_value = 0.0, 0.15
    links.new(z, horizon.inputs["Value"])
    amount = _math(nodes, links, "MULTIPLY", mask.outputs["Result"], horizon.outputs["Result"])
    shade = nodes.new("ShaderNodeMapRange")  # thicker clouds are greyer underneath
    shade.inputs["From Min"].default_value, shade.inputs["From Max"].default_value = threshold, threshold + 0.3
    shade.inputs["To Min"].default_value, shade.inputs["To Max"].default_value = 0.34, 0.2
    links.new(fac, shade.inputs["Value"])
    white = nodes.new("ShaderNodeCombineColor")
    for channel, tint in zip(("Red", "Green", "Blue"), (0.97, 0.98, 1.0)):
        links.new(_math(nodes, links, "MULTIPLY", shade.outputs["Result"], tint), white.inputs[channel])
    mix = nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    links.new(amount, mix.inputs["Factor"])
    links.new(sky_colour, mix.inputs["A"])
    links.new(white.outputs["Color"], mix.inputs["B"])
    return mix.outputs["Result"]


def _overcast(nodes, links):
    """The CIE overcast sky, (1 + 2 z) / 3 of the zenith's radiance at height z of the view
    direction, with faint cloud texture; the ground below the horizon a third of it."""
    fac, z = _cloud_noise(nodes, links, 1.2)
    height = _math(nodes, links, "MAXIMUM", z, 0.0)
    cie = _math(nodes, links, "MULTIPLY_ADD", height, 2.0 / 3.0)
    cie.node.inputs[2].default_value = 1.0 / 3.0
    texture = nodes.new("ShaderNodeMapRange")
    texture.inputs["To Min"].default_value, texture.inputs["To Max"].default_value = 0.8, 1.15
    links.new(fac, texture.inputs["Value"])
    level = _math(nodes, links, "MULTIPLY", cie, texture.outputs["Result"])
    colour = nodes.new("ShaderNodeCombineColor")
    for channel, value in zip(("Red", "Green", "Blue"), OVERCAST_COLOUR):
        links.new(_math(nodes, links, "MULTIPLY", level, value), colour.inputs[channel])
    return colour.outputs["Color"]


def wet_ground(material, wetness: float) -> None:
    """Darken ``material`` and make it glossy by ``wetness`` (0-1), with puddles: a low fractal
    noise over the object's coordinates (features about 10 m across) above a threshold that
    falls with wetness makes water on the level faces (normals within about 14 degrees of up):
    mirror-smooth, the soil showing through a third as bright (shallow, muddy)."""
    nodes, links = material.node_tree.nodes, material.node_tree.links
    bsdf = nodes["Principled BSDF"]
    coords = nodes.new("ShaderNodeTexCoord")
    noise = nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 0.09
    noise.inputs["Detail"].default_value = 4.0
    links.new(coords.outputs["Object"], noise.inputs["Vector"])
    puddle = nodes.new("ShaderNodeMapRange")
    puddle.label = PUDDLES
    start = 0.62 - 0.1 * wetness
    puddle.inputs["From Min"].default_value, puddle.inputs["From Max"].default_value = start, start + 0.02
    links.new(noise.outputs["Fac"], puddle.inputs["Value"])
    geometry = nodes.new("ShaderNodeNewGeometry")  # water lies on level ground only: not on a heap or a pit's side
    up = nodes.new("ShaderNodeSeparateXYZ")
    links.new(geometry.outputs["Normal"], up.inputs["Vector"])
    level = nodes.new("ShaderNodeMapRange")
    level.inputs["From Min"].default_value, level.inputs["From Max"].default_value = 0.97, 0.995
    links.new(up.outputs["Z"], level.inputs["Value"])
    pooled = _math(nodes, links, "MULTIPLY", puddle.outputs["Result"], level.outputs["Result"])
    base = bsdf.inputs["Base Color"]
    darker = nodes.new("ShaderNodeMix")  # wet soil: about half as bright
    darker.data_type = "RGBA"
    darker.blend_type = "MULTIPLY"
    darker.inputs["Factor"].default_value = 1.0
    if base.links:
        links.new(base.links[0].from_socket, darker.inputs["A"])
    else:
        darker.inputs["A"].default_value = base.default_value
    shade = 1.0 - 0.5 * wetness
    darker.inputs["B"].default_value = (shade, shade, shade, 1.0)
    water = nodes.new("ShaderNodeMix")  # shallow muddy water: the soil shows through, a third as bright
    water.data_type = "RGBA"
    water.blend_type = "MULTIPLY"
    links.new(pooled, water.inputs["Factor"])
    links.new(darker.outputs["Result"], water.inputs["A"])
    water.inputs["B"].default_value = (0.33, 0.34, 0.35, 1.0)
    links.new(water.outputs["Result"], base)
    rough = bsdf.inputs["Roughness"]
    dry = float(rough.default_value)
    smooth = nodes.new("ShaderNodeMapRange")  # damp ground loses most of its roughness, puddles all
    smooth.inputs["To Min"].default_value = float(np.clip(dry * (1.0 - 0.4 * wetness), 0.05, 1.0))
    smooth.inputs["To Max"].default_value = 0.02
    links.new(pooled, smooth.inputs["Value"])
    links.new(smooth.outputs["Result"], rough)
