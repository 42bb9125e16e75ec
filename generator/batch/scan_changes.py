"""The change label of every LiDAR return on a timeline (``--phases K --lidar NAME``; bpy-free;
docs/lidar.md, "Over time"): once ``changes.h5`` is written, each return of stage k > 0 gets
the change status, since stage k - 1, of the surface it met (exporters.changes.STATUS codes):
the status of its object (unchanged, added, moved), and for an object that grew (a building
with new floors) ``grown`` where the surface point the beam met (without the range noise:
``Scan.xyz_exact``) lies farther than the changes' point tolerance (1 cm) from stage k - 1's
surface and ``unchanged`` where it lies on it, the rule of changes.h5's ``points_added``.
Stage 0's returns have none."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def surface_points(scan) -> np.ndarray:
    """(N, 3) world positions of the surface points the returns met, without the range noise
    (``Scan.xyz_exact``; the noisy points where a sweep did not keep them)."""
    from ..geometry.camera import apply_affine

    if scan.xyz_exact is None:
        return scan.world_points()
    return apply_affine(scan.world_from_sensor, scan.xyz_exact.astype(np.float64))


def label_scan_changes(folder: Path, stages: list[Path], kinds: list[str]) -> int:
    """Write the change labels of every scan of stages 1..K-1 of the timeline ``folder``
    (``stages``: the K stages' folders, in order); returns the number of scans labelled."""
    from exporters.changes import STATUS, read_changes
    from exporters.ground_truth import read_ground_truth
    from exporters.semantickitti import read_lidar_json, read_scan, write_scan_changes

    from ..scene import changes as ch

    changes = read_changes(folder, masks=False)
    labelled = 0
    for k in range(1, len(stages)):
        status, table = changes.pairs[k].status, changes.stage_tables[k]
        before = [p for p in read_ground_truth(stages[k - 1]).parts if len(p.faces)]
        for kind in kinds:
            root = stages[k] / kind / "lidar"
            for scans in sorted(p.parent for p in root.glob("*/lidar.json")) if root.is_dir() else []:
                doc = read_lidar_json(scans)
                out = []
                for i in range(len(doc["scans"])):
                    scan = read_scan(scans, i, doc)
                    code = status[table[scan.instance.astype(np.int64)]].astype(np.int8)
                    grown = np.flatnonzero(code == STATUS.index("grown"))
                    if len(grown):
                        on_old = ch.surface_distance(surface_points(scan)[grown], before) <= ch.POINT_TOLERANCE
                        code[grown[on_old]] = STATUS.index("unchanged")
                    out.append(code)
                write_scan_changes(scans, out)
                labelled += len(out)
    return labelled
