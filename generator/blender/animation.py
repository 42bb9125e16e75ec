"""Which objects move: own or inherited transform animation (keyframes, drivers, constraints)."""

from __future__ import annotations

import bpy

TRANSFORM_PATHS = {
    "location",
    "rotation_euler",
    "rotation_quaternion",
    "rotation_axis_angle",
    "scale",
    "delta_location",
    "delta_rotation_euler",
    "delta_rotation_quaternion",
    "delta_scale",
    "matrix_world",
    "matrix_basis",
    "matrix_local",
    "matrix_parent_inverse",
}


def _fcurve_varies(fcurve) -> bool:
    if fcurve.mute:
        return False
    if any(not m.mute for m in fcurve.modifiers):
        return True
    values = [k.co[1] for k in fcurve.keyframe_points]
    return len(values) > 1 and (max(values) - min(values)) > 1e-9


def _action_fcurves(action, slot):
    if action is None:
        return []
    from bpy_extras import anim_utils

    channelbag = anim_utils.action_get_channelbag_for_slot(action, slot) if slot is not None else None
    if channelbag is not None:
        return list(channelbag.fcurves)
    # No slot assigned: consider every channelbag of the action.
    out = []
    for layer in action.layers:
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", []):
                out.extend(bag.fcurves)
    return out


def transform_is_animated(obj) -> bool:
    """True if ``obj``'s own transform is driven by varying keyframes, F-curve modifiers,
    active NLA strips or drivers."""
    ad = obj.animation_data
    if ad is None:
        return False
    curves = _action_fcurves(ad.action, ad.action_slot)
    for track in ad.nla_tracks:
        if track.mute:
            continue
        for strip in track.strips:
            if not strip.mute and strip.action is not None:
                curves.extend(_action_fcurves(strip.action, getattr(strip, "action_slot", None)))
    if any(fc.data_path in TRANSFORM_PATHS and _fcurve_varies(fc) for fc in curves):
        return True
    return any(
        fc.data_path in TRANSFORM_PATHS and not fc.mute and fc.driver is not None and fc.driver.is_valid
        for fc in ad.drivers
    )


def dynamic_object_names() -> set[str]:
    """Names of objects that move: their own transform is animated, or an ancestor's is, or
    a constraint targets a moving object."""
    memo: dict[str, bool] = {}

    def is_dynamic(obj, stack=()) -> bool:
        if obj.name in memo:
            return memo[obj.name]
        if obj.name in stack:
            return False
        stack = stack + (obj.name,)
        result = transform_is_animated(obj)
        if not result and obj.parent is not None:
            result = is_dynamic(obj.parent, stack)
        if not result:
            for con in obj.constraints:
                if con.mute or not getattr(con, "enabled", True):
                    continue
                target = getattr(con, "target", None)
                if target is not None and target.name != obj.name and (
                    is_dynamic(target, stack) or con.type == "FOLLOW_PATH"
                ):
                    result = True
                    break
        memo[obj.name] = result
        return result

    return {o.name for o in bpy.data.objects if is_dynamic(o)}
