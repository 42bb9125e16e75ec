"""A trajectory's LiDAR sweeps in a Rerun recording (docs/viewer.md, docs/lidar.md):

    world/<kind>/lidar/<NAME>     per sweep, its returns at their world positions (the scene
                                  frozen at the sweep's start), coloured by class

logged at the sweep's start on the ``time`` timeline and at the frame that starts with it
(or the nearest before) on the ``frame`` timeline.
"""

from __future__ import annotations

import numpy as np

from datasets.scans import checked, sensors_of
from exporters.semantickitti import read_lidar_json, read_scan, scan_folder

from .common import FRAME_TIMELINE, TIME_TIMELINE, class_ids

LIDAR_RADIUS_UI = 1.0  # UI points: tens of thousands of returns a sweep


def log_scans(rec, seq) -> int:
    """Log every sweep of every sensor of the trajectory ``seq`` (a datasets.Sequence);
    returns the number of sweeps logged."""
    import rerun as rr

    count = 0
    for name in sensors_of(seq.folder):
        folder = scan_folder(seq.folder, name)
        doc = checked(read_lidar_json, folder)
        for k in range(len(doc["scans"])):
            scan = checked(read_scan, folder, k, doc)
            frame = max(0, int(np.searchsorted(seq.timestamps, scan.start_time_s + 1e-9, side="right")) - 1)
            rec.set_time(FRAME_TIMELINE, sequence=frame)
            rec.set_time(TIME_TIMELINE, duration=scan.start_time_s)
            rec.log(f"world/{seq.kind}/lidar/{name}", rr.Points3D(scan.world_points().astype(np.float32),
                                                                  class_ids=class_ids(scan.label.astype(np.int64)),
                                                                  radii=rr.Radius.ui_points(LIDAR_RADIUS_UI)))
            count += 1
    return count
