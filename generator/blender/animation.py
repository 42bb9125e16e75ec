"""Which objects move, and motion the Simulator cannot follow.

An object moves when its own transform is animated (keyframes, F-curve modifiers, NLA strips,
drivers), an ancestor moves, it hangs from a bone of an armature whose pose is animated, or a
constraint targets something that moves. Each moving object's per-frame world matrix is read
from the evaluated scene (extract.dynamic_matrices); see docs/rendering.md, "What of a .blend
is honoured".
"""

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
# what a render shows of an object, read once at load (session.make_viewport_match_render)
VISIBILITY_PATHS = {"hide_render", "visible_camera", "is_holdout", "show_instancer_for_render"}


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


def object_fcurves(id_data) -> list:
    """The F-curves of ``id_data``'s active action (none without one)."""
    ad = getattr(id_data, "animation_data", None)
    return [] if ad is None else _action_fcurves(ad.action, ad.action_slot)


def varying_paths(id_data) -> set[str]:
    """Data paths of a datablock (object, camera, shape keys...) driven by varying keyframes,
    F-curve modifiers, active NLA strips or valid drivers."""
    ad = getattr(id_data, "animation_data", None) if id_data is not None else None
    if ad is None:
        return set()
    curves = _action_fcurves(ad.action, ad.action_slot)
    for track in ad.nla_tracks:
        if track.mute:
            continue
        for strip in track.strips:
            if not strip.mute and strip.action is not None:
                curves.extend(_action_fcurves(strip.action, getattr(strip, "action_slot", None)))
    paths = {fc.data_path for fc in curves if _fcurve_varies(fc)}
    return paths | {fc.data_path for fc in ad.drivers if not fc.mute and fc.driver is not None and fc.driver.is_valid}


def transform_is_animated(obj) -> bool:
    """True if ``obj``'s own transform is driven by varying keyframes, F-curve modifiers,
    active NLA strips or drivers."""
    return not TRANSFORM_PATHS.isdisjoint(varying_paths(obj))


class Motion:
    """Memoised "does this object move?", with ``static`` objects taken as fixed (to ask
    whether an instanced object moves relative to its instancer)."""

    def __init__(self, static=()):
        self._memo = {name: False for name in static}

    def moves(self, obj, stack=()) -> bool:
        if obj.name in self._memo:
            return self._memo[obj.name]
        if obj.name in stack:
            return False
        stack = stack + (obj.name,)
        parent = obj.parent
        result = (transform_is_animated(obj)
                  or (parent is not None and self.moves(parent, stack))
                  or (parent is not None and obj.parent_type == "BONE" and self.pose_moves(parent, stack))
                  or any(self._constraint_moves(con, obj, stack) for con in obj.constraints))
        self._memo[obj.name] = result
        return result

    def pose_moves(self, arm, stack=()) -> bool:
        """True if an armature's pose is animated or constrained to something that moves."""
        if arm.type != "ARMATURE" or arm.pose is None:
            return False
        if any(p.startswith("pose.bones") for p in varying_paths(arm)):
            return True
        return any(self._constraint_moves(con, arm, stack) for pb in arm.pose.bones for con in pb.constraints)

    def _constraint_moves(self, con, owner, stack) -> bool:
        if con.mute or not getattr(con, "enabled", True):
            return False
        # one target, or an Armature constraint's list of (armature, bone) targets
        targets = [(t.target, t.subtarget) for t in con.targets] if hasattr(con, "targets") else [
            (getattr(con, "target", None), getattr(con, "subtarget", ""))]
        return any(self._target_moves(con, target, bone, owner, stack) for target, bone in targets)

    def _target_moves(self, con, target, bone, owner, stack) -> bool:
        if target is None or target.name == owner.name:
            return False
        return con.type == "FOLLOW_PATH" or self.moves(target, stack) or (bool(bone) and self.pose_moves(target, stack))


def dynamic_object_names() -> set[str]:
    """Names of objects that move (see the module docstring)."""
    motion = Motion()
    return {o.name for o in bpy.data.objects if motion.moves(o)}


def moves_within(obj, instancer) -> bool:
    """True if ``obj`` moves with ``instancer`` held still: an instanced object with its own motion."""
    return Motion(static=(instancer.name,)).moves(obj)


def animated_visibility(objects) -> str | None:
    """A one-line refusal if the render visibility of one of ``objects`` is keyframed or
    driven (it is read once at load), else None. Collections' visibility cannot be animated."""
    for obj in sorted(objects, key=lambda o: o.name):
        animated = sorted(p for p in varying_paths(obj) if p in VISIBILITY_PATHS or p.endswith(".show_render"))
        if animated:
            return (f"object {obj.name!r} has animated render visibility ({animated[0]}), which is read once at load; "
                    "remove those keyframes or drivers (move the object out of view instead)")
    return None


def deforming(objects) -> str | None:
    """A one-line refusal if one of ``objects`` (the rendered ones) is deformed over time by
    animated shape keys or an animated armature (the simulator's parts are rigid), else None."""
    motion = Motion()
    for obj in sorted(objects, key=lambda o: o.name):
        if varying_paths(getattr(obj.data, "shape_keys", None)):
            return (f"object {obj.name!r} has animated shape keys (a deforming mesh); parts are rigid: "
                    "apply or remove them")
        arms = [mod.object for mod in obj.modifiers if mod.type == "ARMATURE" and mod.show_render and mod.object]
        if obj.parent is not None and obj.parent_type == "ARMATURE":  # a hidden armature deform
            arms.append(obj.parent)
        for arm in arms:
            if motion.pose_moves(arm) or (motion.moves(arm) and not motion.moves(obj)):
                return (f"object {obj.name!r} is deformed by the animated armature {arm.name!r}; parts are rigid: "
                        "parent it to a bone instead, or apply the modifier")
    return None
