"""Procedural materials for generated sites, with seeded colour and roughness variation."""

from __future__ import annotations

import colorsys

import bpy
import numpy as np

from ..geometry.seeding import stream

# key: (base colour linear RGB, roughness, metallic, noise) where noise is None or
# (scale, second colour, mix strength): a procedural pattern (dirt, rust, grain, stains).
RECIPES: dict[str, tuple] = {
    "default": ((0.5, 0.5, 0.5), 0.6, 0.0, None),
    "ground": ((0.23, 0.18, 0.12), 0.9, 0.0, (0.15, (0.12, 0.1, 0.08), 0.6)),
    "concrete": ((0.45, 0.44, 0.41), 0.85, 0.0, (3.0, (0.33, 0.32, 0.3), 0.5)),
    "concrete_dark": ((0.32, 0.31, 0.3), 0.85, 0.0, (3.0, (0.24, 0.23, 0.22), 0.5)),
    "concrete_white": ((0.65, 0.64, 0.6), 0.8, 0.0, (4.0, (0.45, 0.44, 0.42), 0.4)),
    "concrete_block": ((0.4, 0.4, 0.38), 0.9, 0.0, (8.0, (0.3, 0.3, 0.29), 0.4)),
    "brick": ((0.42, 0.12, 0.06), 0.85, 0.0, (10.0, (0.3, 0.08, 0.05), 0.5)),
    "rebar": ((0.25, 0.12, 0.06), 0.7, 0.6, (20.0, (0.4, 0.18, 0.07), 0.6)),
    "steel_rust": ((0.3, 0.14, 0.06), 0.75, 0.4, (6.0, (0.15, 0.12, 0.1), 0.6)),
    "steel_galvanized": ((0.55, 0.56, 0.57), 0.45, 1.0, (12.0, (0.4, 0.4, 0.41), 0.3)),
    "steel_painted": ((0.2, 0.2, 0.21), 0.5, 0.3, None),
    "steel_dark": ((0.05, 0.05, 0.05), 0.6, 0.4, (5.0, (0.12, 0.1, 0.08), 0.4)),
    "steel_cable": ((0.1, 0.1, 0.1), 0.4, 1.0, None),
    "crane_paint": ((0.8, 0.55, 0.02), 0.45, 0.2, (6.0, (0.5, 0.35, 0.05), 0.2)),
    "crane_hook": ((0.8, 0.1, 0.05), 0.4, 0.2, None),
    "formwork": ((0.75, 0.45, 0.05), 0.6, 0.0, (5.0, (0.55, 0.4, 0.2), 0.4)),
    "wood": ((0.45, 0.3, 0.15), 0.75, 0.0, (18.0, (0.32, 0.2, 0.1), 0.5)),
    "wood_dark": ((0.25, 0.16, 0.08), 0.8, 0.0, (18.0, (0.15, 0.1, 0.05), 0.5)),
    "glass": ((0.02, 0.03, 0.04), 0.05, 0.0, None),
    "rubber": ((0.02, 0.02, 0.02), 0.9, 0.0, None),
    "sand": ((0.6, 0.45, 0.25), 0.95, 0.0, (25.0, (0.45, 0.33, 0.18), 0.4)),
    "gravel": ((0.35, 0.34, 0.32), 0.9, 0.0, (60.0, (0.15, 0.15, 0.14), 0.7)),
    "rubble": ((0.3, 0.27, 0.24), 0.95, 0.0, (30.0, (0.15, 0.12, 0.1), 0.6)),
    "truck_paint": ((0.7, 0.25, 0.03), 0.35, 0.3, (4.0, (0.3, 0.22, 0.15), 0.2)),
    "mixer_drum": ((0.75, 0.75, 0.72), 0.4, 0.3, (5.0, (0.45, 0.42, 0.38), 0.4)),
    "excavator_paint": ((0.85, 0.55, 0.02), 0.4, 0.2, (5.0, (0.35, 0.3, 0.2), 0.25)),
    "cabin_paint": ((0.75, 0.76, 0.74), 0.5, 0.1, (5.0, (0.5, 0.5, 0.48), 0.2)),
    "door_paint": ((0.1, 0.2, 0.45), 0.5, 0.1, None),
    "container_blue": ((0.04, 0.14, 0.4), 0.55, 0.3, (4.0, (0.3, 0.15, 0.07), 0.3)),
    "container_red": ((0.45, 0.05, 0.03), 0.55, 0.3, (4.0, (0.3, 0.15, 0.07), 0.3)),
    "container_green": ((0.05, 0.25, 0.1), 0.55, 0.3, (4.0, (0.3, 0.15, 0.07), 0.3)),
    "container_grey": ((0.3, 0.31, 0.32), 0.55, 0.3, (4.0, (0.3, 0.15, 0.07), 0.3)),
    "container_orange": ((0.7, 0.28, 0.03), 0.55, 0.3, (4.0, (0.3, 0.15, 0.07), 0.3)),
    "container_white": ((0.7, 0.7, 0.68), 0.55, 0.3, (4.0, (0.3, 0.15, 0.07), 0.3)),
    "plastic_orange": ((0.9, 0.2, 0.01), 0.4, 0.0, None),
    "plastic_white": ((0.8, 0.8, 0.8), 0.4, 0.0, None),
    "plastic_toilet": ((0.03, 0.3, 0.1), 0.4, 0.0, None),
    "plastic_toilet_door": ((0.02, 0.2, 0.07), 0.4, 0.0, None),
    "reflective_white": ((0.9, 0.9, 0.9), 0.25, 0.0, None),
    "skip_paint": ((0.7, 0.5, 0.02), 0.6, 0.2, (5.0, (0.3, 0.15, 0.05), 0.5)),
    "generator_paint": ((0.1, 0.35, 0.1), 0.5, 0.2, None),
    "hivis": ((0.9, 0.7, 0.0), 0.6, 0.0, None),
    "work_trousers": ((0.05, 0.06, 0.1), 0.9, 0.0, None),
    "skin": ((0.55, 0.35, 0.25), 0.6, 0.0, None),
    "hard_hat": ((0.9, 0.9, 0.85), 0.35, 0.0, None),
}


def _jitter(rgb, rng: np.random.Generator, hue=0.02, sat=0.1, val=0.12):
    h, s, v = colorsys.rgb_to_hsv(*rgb)
    h = (h + rng.uniform(-hue, hue)) % 1.0
    s = float(np.clip(s * (1 + rng.uniform(-sat, sat)), 0, 1))
    v = float(np.clip(v * (1 + rng.uniform(-val, val)), 0, 1))
    return colorsys.hsv_to_rgb(h, s, v)


def make_material(key: str, seed: int):
    """The material ``key`` of this site's seed (created once per file)."""
    name = f"site_{key}"
    if name in bpy.data.materials:
        return bpy.data.materials[name]
    base, rough, metal, noise = RECIPES.get(key, RECIPES["default"])
    rng = stream(seed, "material", key)
    mat = bpy.data.materials.new(name)
    if mat.node_tree is None:
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes.get("Principled BSDF") or nodes.new("ShaderNodeBsdfPrincipled")
    colour = _jitter(base, rng)
    roughness = float(np.clip(rough + rng.uniform(-0.1, 0.1), 0.02, 1.0))
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metal
    if key == "ground":  # the paper's ground: random roughness and reflectance
        bsdf.inputs["Roughness"].default_value = float(rng.uniform(0.5, 1.0))
        bsdf.inputs["Specular IOR Level"].default_value = float(rng.uniform(0.1, 0.7))
    if noise is None:
        bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    else:
        scale, second, strength = noise
        tex = nodes.new("ShaderNodeTexNoise")
        tex.inputs["Scale"].default_value = scale * float(rng.uniform(0.8, 1.25))
        tex.inputs["Detail"].default_value = 6.0
        mix = nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.inputs["Factor"].default_value = strength
        ramp = nodes.new("ShaderNodeMapRange")
        ramp.inputs["From Min"].default_value = 0.35
        ramp.inputs["From Max"].default_value = 0.65
        links.new(tex.outputs["Fac"], ramp.inputs["Value"])
        links.new(ramp.outputs["Result"], mix.inputs["Factor"])
        mix.inputs["A"].default_value = (*colour, 1.0)
        mix.inputs["B"].default_value = (*_jitter(second, rng), 1.0)
        links.new(mix.outputs["Result"], bsdf.inputs["Base Color"])
    mat.diffuse_color = (*colour, 1.0)  # viewport / Workbench colour
    return mat
