"""Training data for change detection from timelines (``python -m generator --phases K``; no
bpy, torch optional; docs/phases.md).

    from datasets.change import ChangePairDataset, change_clouds
    pairs = ChangePairDataset(["output/seed_000000"])           # every consecutive pair of stages
    item = pairs[0]      # before, after (frame dicts, same pose), change (H, W) bool, stages, K, pose
    clouds = change_clouds("output/seed_000000", 0, 1)          # both stages' GT clouds with change labels
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from generator.checks import check_integer, items

from .scene import DatasetError, MissingKeyError, Sequence, check_index, read_labels, read_point_cloud, seed_fields
from .tasks import TaskDataset, checked_keys, to_tensor, trajectory_kinds


class Timeline:
    """A seed folder made with ``--phases K``: its stages' trajectories and its changes.h5."""

    def __init__(self, path: str | Path):
        from exporters.changes import FILE, read_changes
        from exporters.hdf5 import AccessError, DamagedFileError
        from exporters.manifest import read_manifest

        self.path = Path(path)
        manifest = read_manifest(self.path)
        if manifest is None or not (self.path / FILE).is_file():
            raise DatasetError(f"{self.path}: not a complete timeline seed folder (manifest.json and {FILE}); "
                               "point at output/seed_NNNNNN written by python -m generator --phases K")
        self.seed, self.trajectories = seed_fields(manifest, self.path)
        try:
            self.changes = read_changes(self.path)
        except (DamagedFileError, ValueError, AccessError) as exc:
            raise DatasetError(str(exc)) from None
        self.stages = self.changes.stages
        self.labels = read_labels(self.path / "phase_0")
        self._sequences: dict[tuple[int, str], Sequence] = {}

    def sequence(self, stage: int, kind: str) -> Sequence:
        """Stage ``stage``'s frames (Python indexing: -1 is the last stage) of trajectory
        ``kind`` (datasets.scene.Sequence)."""
        stage = check_index(stage, self.stages, "stage")
        if kind not in self.trajectories:
            raise MissingKeyError(f"no trajectory {kind!r} in {self.path} (has {', '.join(self.trajectories)})")
        if (stage, kind) not in self._sequences:
            self._sequences[stage, kind] = Sequence(self.path / f"phase_{stage}" / kind, self.labels)
        return self._sequences[stage, kind]


class ChangePairDataset(TaskDataset):
    """Pairs of frames with the same pose at consecutive stages, and what changed between them.

    Item: ``before`` and ``after`` (dicts of the frames' modalities, as FrameDataset's, K and
    pose included; the poses are the same), ``change`` (H, W) bool (the pixel's visible
    surface changed, changes.h5), ``stages`` (k-1, k), ``scene`` (seed), ``trajectory``,
    ``index``. ``pairs``: the k of the pairs (k-1, k) to include (default: all);
    ``trajectories`` and ``keys`` (one name or several) are checked here, as FrameDataset's;
    ``transform`` is applied to ``before``, ``after`` and ``change`` each (the mask as an id
    map: nearest pixel centre, cropped with the frames)."""

    def __init__(self, paths, pairs: list[int] | None = None, trajectories: list[str] | None = None,
                 transform: Callable | None = None, as_tensor: bool = False, keys: tuple[str, ...] | None = None):
        super().__init__(transform, as_tensor)
        paths = [paths] if isinstance(paths, (str, Path, Timeline)) else list(paths)
        self.timelines = [p if isinstance(p, Timeline) else Timeline(p) for p in paths]
        if not self.timelines:
            raise DatasetError("no timelines given")
        if pairs is not None and items(pairs) is None:
            raise DatasetError(f"pairs must be a list of integers k (the pairs of stages k-1, k), got {pairs!r}")
        kinds = trajectory_kinds(self.timelines, trajectories)
        self.index: list[tuple[int, int, str, int]] = []
        sequences: list[Sequence] = []
        for s, tl in enumerate(self.timelines):
            valid = f"an integer from 1 to {tl.stages - 1} for {tl.path} (stage k-1 to stage k)"
            ks = range(1, tl.stages) if pairs is None else [check_integer("pair", k, 1, tl.stages - 1, valid=valid)
                                                            for k in items(pairs)]
            if len(set(ks)) != len(ks):
                raise DatasetError(f"pairs lists pair {next(k for k in ks if ks.count(k) > 1)} twice; give each once")
            for k in ks:
                for kind in kinds[s]:
                    sequences += [tl.sequence(k - 1, kind), tl.sequence(k, kind)]
                    self.index += [(s, k, kind, i) for i in range(len(sequences[-1]))]
        self.keys = checked_keys(keys, sequences)

    def __len__(self) -> int:
        return len(self.index)

    def __getitem__(self, i: int) -> dict:
        s, k, kind, j = self.index[check_index(i, len(self), "ChangePairDataset item")]
        tl = self.timelines[s]
        before = tl.sequence(k - 1, kind).read(j, self.keys).as_dict()
        after = tl.sequence(k, kind).read(j, self.keys).as_dict()
        change = tl.changes.pair(k - 1, k).masks[kind][j]
        if self.transform is not None:
            before, after = self.transform(before), self.transform(after)
            # the mask goes through the same transform as an id map (nearest, cropped, resized)
            change = self.transform({"instance": change.astype(np.int32), "K": after["K"]})["instance"] == 1
        sample = {"before": before, "after": after, "change": change, "stages": np.array([k - 1, k]),
                  "K": after["K"], "pose": after["pose"], "scene": tl.seed, "trajectory": kind, "index": j}
        return to_tensor(sample) if self.as_tensor else sample


def change_clouds(path: str | Path | Timeline, before: int, after: int) -> dict:
    """The two stages' ground-truth clouds with their change labels: ``before`` and ``after``
    dicts with xyz (N, 3) float32 metres, label, instance (stage ids) and union_instance (ids
    of changes.h5's instance table) (N,) int32, and ``removed`` (stage ``before``) /
    ``added`` (stage ``after``) (N,) bool; ``status`` per union instance (exporters.changes.STATUS
    codes, -1 absent) and ``transform`` (U, 4, 4) for moved ones; ``names`` the union table.
    The stages' points.ply are read by :func:`datasets.scene.read_point_cloud` (its checks and errors)."""
    tl = path if isinstance(path, Timeline) else Timeline(path)
    try:
        pair = tl.changes.pair(before, after)
    except ValueError as exc:
        raise DatasetError(str(exc)) from None
    out = {"status": pair.status, "transform": pair.transform, "names": tl.changes.names}
    for key, stage, flag, values in (("before", before, "removed", pair.points_removed),
                                     ("after", after, "added", pair.points_added)):
        cloud = read_point_cloud(tl.path / f"phase_{stage}")
        table = tl.changes.stage_tables[stage]
        out[key] = {"xyz": cloud["xyz"], "label": cloud["label"], "instance": cloud["instance"],
                    "union_instance": table[cloud["instance"]], flag: values}
    return out
