"""``seed_N/changes.h5``: what changed between consecutive stages of a site's timeline
(``python -m generator --phases K``; definitions and tolerances in docs/phases.md).

One writer (:func:`write_changes`) and one reader (:func:`read_changes`). Checksummed HDF5
like ``scene.h5`` (Fletcher-32 on every dataset, 1.10 metadata). Layout:

- attributes ``format_version``, ``stages`` (K), ``labels`` (JSON), ``status`` (JSON list: code
  -> name), ``parameters`` (JSON: tolerances in metres, trajectories), ``conventions``;
- ``instances/name`` (U,) the objects of every stage (union table, sorted names),
  ``instances/label`` (U,) label ids;
- ``stages/<k>/instance_to_union`` (n_k,) i4: stage k's instance id (frames, points.ply,
  scene.h5) -> union id; the identity for timelines written by ``generator/batch/phases.py``,
  whose stages share one object table (an object a stage lacks is an empty entry there);
- ``pairs/<k>`` for k = 1..K-1, the change from stage k-1 to stage k:
  ``status`` (U,) i1 (-1: in neither stage), ``transform`` (U, 4, 4) f8 (stage k-1 world ->
  stage k world for moved objects, identity otherwise),
  ``points_added`` (N_k,) bool and ``distance_added`` (N_k,) f4 over stage k's points.ply,
  ``points_removed`` (N_{k-1},) bool and ``distance_removed`` (N_{k-1},) f4 over stage k-1's,
  ``frames/<trajectory>/mask`` (T, H, W) bool: pixels whose visible surface changed.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import FORMAT_VERSION
from .hdf5 import (H5_ERRORS, DamagedFileError, attribute, create_file, damaged, dataset, group, open_file, read,
                   reason, text, text_attribute)

FILE = "changes.h5"
STATUS = ("unchanged", "added", "removed", "moved", "grown")  # the codes of pairs/<k>/status; -1 absent
KW = {"compression": "gzip", "compression_opts": 4}


@dataclass
class ChangePair:
    """The change from stage ``k - 1`` to stage ``k`` (see the module docstring)."""

    k: int
    status: np.ndarray
    transform: np.ndarray
    points_added: np.ndarray
    distance_added: np.ndarray
    points_removed: np.ndarray
    distance_removed: np.ndarray
    masks: dict[str, np.ndarray] = field(default_factory=dict)

    def instances_with(self, name: str) -> np.ndarray:
        """Union ids whose status is ``name`` (one of STATUS)."""
        return np.flatnonzero(self.status == STATUS.index(name))


@dataclass
class Changes:
    path: Path
    stages: int
    labels: list[str]
    names: list[str]
    instance_labels: np.ndarray
    stage_tables: list[np.ndarray]
    parameters: dict
    pairs: dict[int, ChangePair]

    def pair(self, before: int, after: int) -> ChangePair:
        """The change between stages ``before`` and ``after`` = ``before`` + 1; ValueError otherwise."""
        if after != before + 1 or after not in self.pairs:
            raise ValueError(f"{self.path}: no change from stage {before} to stage {after}; stages are 0 to "
                             f"{self.stages - 1} and changes go from one stage to the next (k-1 k)")
        return self.pairs[after]


def write_changes(path: str | Path, *, labels: list[str], names: list[str], instance_labels: np.ndarray,
                  stage_tables: list[np.ndarray], pairs: list[ChangePair], parameters: dict) -> Path:
    path = Path(path)
    with create_file(path) as f:
        f.attrs.update({"format_version": FORMAT_VERSION, "stages": len(stage_tables),
                        "labels": text_attribute(json.dumps(labels)), "status": text_attribute(json.dumps(STATUS)),
                        "parameters": text_attribute(json.dumps(parameters, sort_keys=True)),
                        "conventions": text_attribute(
                            "metres; world Z up; status per union object (instances/name); transform maps stage k-1 "
                            "world to stage k world; points over each stage's ground_truth/points.ply rows; masks "
                            "(T, H, W) over each trajectory's frames, True = the visible surface changed")})
        g = f.create_group("instances")
        dataset(g, "name", np.array(names, dtype=object))
        dataset(g, "label", np.asarray(instance_labels, np.int32))
        s = f.create_group("stages")
        for k, table in enumerate(stage_tables):
            dataset(s.create_group(str(k)), "instance_to_union", np.asarray(table, np.int32))
        p = f.create_group("pairs")
        for pair in pairs:
            q = p.create_group(str(pair.k))
            dataset(q, "status", np.asarray(pair.status, np.int8))
            dataset(q, "transform", np.asarray(pair.transform, np.float64))
            for key in ("points_added", "points_removed"):
                dataset(q, key, np.asarray(getattr(pair, key), bool), **KW)
            for key in ("distance_added", "distance_removed"):
                dataset(q, key, np.asarray(getattr(pair, key), np.float32), **KW)
            fr = q.create_group("frames")
            for kind, mask in pair.masks.items():
                mask = np.asarray(mask, bool)
                dataset(fr.create_group(kind), "mask", mask, chunks=(1, *mask.shape[1:]), **KW)
    return path


def read_changes(path: str | Path, masks: bool = True) -> Changes:
    """Read ``changes.h5`` (a seed folder or the file); ``masks=False`` skips the frame masks.
    A damaged file raises DamagedFileError, a file of another format version ValueError."""
    path = Path(path)
    if path.is_dir():
        path = path / FILE
    with open_file(path) as f:
        try:
            version = text(attribute(f, "format_version", path))
            if version != FORMAT_VERSION:
                raise ValueError(f"{path}: changes format {version!r}, this reader reads {FORMAT_VERSION} "
                                 "(regenerate the seed: python -m generator --seeds N --phases K --overwrite)")
            stages = int(attribute(f, "stages", path))
            labels = json.loads(text(attribute(f, "labels", path)))
            parameters = json.loads(text(attribute(f, "parameters", path)))
            names = [text(n) for n in read(f, "instances/name", path)]
            instance_labels = read(f, "instances/label", path)
            tables = [read(f, f"stages/{k}/instance_to_union", path) for k in range(stages)]
            pairs = {}
            for k in range(1, stages):
                q = group(f, f"pairs/{k}", path)
                kinds = sorted(group(q, "frames", path)) if masks else []
                pairs[k] = ChangePair(k, *(read(q, key, path) for key in (
                    "status", "transform", "points_added", "distance_added", "points_removed", "distance_removed")),
                    masks={kind: read(q, f"frames/{kind}/mask", path) for kind in kinds})
        except (DamagedFileError, ValueError) as exc:
            if isinstance(exc, DamagedFileError) or str(exc).startswith(str(path)):
                raise
            raise damaged(path, reason(exc)) from None
        except H5_ERRORS as exc:
            raise damaged(path, reason(exc)) from None
    return Changes(path, stages, labels, names, instance_labels, tables, parameters, pairs)
