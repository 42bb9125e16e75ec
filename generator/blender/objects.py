"""The Simulator's object table: which extracted parts it simulates, in which order
(instance id = index), and the label table (label id = index)."""

from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..checks import items
from ..geometry.parts import MeshPart
from . import session
from .extract import MAX_PASS_INDEX, label_of, pass_index_owners, too_many_objects
from .keys import key_names, owner_name


class SceneError(ValueError):
    """The loaded scene cannot be simulated (e.g. it has no geometry)."""


def check_names(name: str, value) -> tuple[str, ...]:
    """``value`` as a tuple of object names, or a one-line error naming the argument."""
    names = items(value)
    if names is None or not all(isinstance(v, str) for v in names):
        raise ValueError(f"{name} must be a list of object names, got {value!r}")
    return names


def object_table(extracted, filter_object_names: tuple[str, ...], instance_names, blend: Path):
    """(parts, dynamic bindings, labels) of the extracted scene: the ``filter_object_names``
    objects dropped, parts ordered as ``instance_names`` when given (docs/simulator-api.md),
    labels as :func:`label_table` orders them. SceneError if the extraction refused the scene
    (a holdout, animated render visibility, motion the rigid parts cannot follow)."""
    if extracted.refusal:
        raise SceneError(f"{blend}: {extracted.refusal}")
    if not extracted.parts:
        raise SceneError(f"{blend} has no render-visible mesh objects with faces (that the camera sees)")
    known = {owner_name(p.name) for p in extracted.parts}
    absent = [n for n in filter_object_names if n not in known]
    if absent:  # a typo would filter nothing; the paper's scripts may name objects a scene lacks
        warnings.warn(f"filter_object_names: {blend} has no mesh object {', '.join(map(repr, absent))}; nothing is "
                      f"filtered for {'it' if len(absent) == 1 else 'them'}", stacklevel=3)
    parts, bindings = _without_objects(extracted.parts, extracted.bindings, filter_object_names)
    if not parts:
        raise SceneError(f"{blend}: filter_object_names leaves no mesh objects")
    if instance_names is not None:
        parts, bindings = _on_instance_table(parts, bindings, check_names("instance_names", instance_names), blend)
    refusal = too_many_objects(len(pass_index_owners(parts)), blend)
    if refusal:
        raise SceneError(refusal)
    return parts, bindings, label_table({p.label for p in parts})


def check_object_count(blend: Path) -> None:
    """SceneError (one line) if the .blend holds more objects than Blender has object pass
    indices, found from the file's index before it is loaded (session.objects_in_file). Every
    object counts, rendered or not: loading such a file would take long before the count of
    the rendered ones were known (the file Blender has open is counted after loading, by
    :func:`object_table`). BlendFileError if the file is missing or unreadable."""
    count = session.objects_in_file(blend)
    if count is not None and count > MAX_PASS_INDEX:
        raise SceneError(too_many_objects(count, blend))


def _without_objects(parts: list[MeshPart], bindings: list, names: tuple[str, ...]):
    """Parts and dynamic bindings without the parts of the named objects (an instance
    belongs to its instancer's name), binding indices renumbered."""
    if not names:
        return parts, bindings
    return _select(parts, bindings, lambda p: owner_name(p.name) not in names)


def filtered_parts(extracted, filter_object_names: tuple[str, ...]):
    """(parts, dynamic bindings) of the ``filter_object_names`` objects alone: not simulated,
    but still surfaces in the image (generator/geometry/pixel_truth.py)."""
    return _select(extracted.parts, extracted.bindings, lambda p: owner_name(p.name) in filter_object_names)


def _select(parts: list[MeshPart], bindings: list, keep_part):
    """The parts for which ``keep_part(part)`` holds and their dynamic bindings, renumbered."""
    keep = [i for i, p in enumerate(parts) if keep_part(p)]
    new_index = {old: new for new, old in enumerate(keep)}
    kept = [replace(b, part=new_index[b.part]) for b in bindings if b.part in new_index]
    return [parts[i] for i in keep], kept


def _on_instance_table(parts: list[MeshPart], bindings: list, names: tuple[str, ...], blend: Path):
    """Parts ordered as ``names`` (an empty static part for a name the scene lacks) and the
    dynamic bindings renumbered."""
    if len(set(names)) != len(names):
        raise ValueError("instance_names has repeated names; give each object once")
    index = {n: i for i, n in enumerate(names)}
    missing = [p.name for p in parts if p.name not in index]
    if missing:
        raise ValueError(f"instance_names lacks {len(missing)} object(s) of {blend}, e.g. {missing[0]!r}; "
                         "give every object of the scene")
    table = [MeshPart(n, label_of(key_names(n)[1]), np.zeros((0, 3)), np.zeros((0, 3), np.int64)) for n in names]
    for p in parts:
        table[index[p.name]] = p
    return table, [replace(b, part=index[parts[b.part].name]) for b in bindings]


def label_table(present: set[str]) -> list[str]:
    """Label names indexed by id: the scene's stored table (``buildee_labels``, e.g. the
    generator's taxonomy) followed by any other labels in sorted order; without a stored
    table, the sorted labels present."""
    stored = session.bpy.context.scene.get("buildee_labels")
    table = list(json.loads(stored)) if isinstance(stored, str) else []
    return table + sorted(present - set(table))
