"""``<kind>/coverage.json``: the share of the site's surface points observed at least once
after each frame of a trajectory (``coverage``, 0..1, within the job's depth limit: 60 m
planar) and the area under that curve over normalised time (``auc``), written by the
``coverage`` sink."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .sinks import FrameRecord, TrajectoryContext, register_sink

FILE_NAME = "coverage.json"


@register_sink("coverage")
class CoverageSink:
    """Collects each frame's coverage; :meth:`close` writes coverage.json with its AUC."""

    def __init__(self, context: TrajectoryContext):
        self.path = Path(context.folder) / FILE_NAME
        self.coverage: list[float] = []

    def add_frame(self, frame: FrameRecord) -> None:
        self.coverage.append(float(frame.coverage))

    def close(self) -> None:
        cov = self.coverage
        auc = float(np.trapezoid(cov, np.linspace(0, 1, len(cov))))  # one frame: 0, as the paper's np.trapz
        self.path.write_text(json.dumps({
            "coverage": cov, "units": "share of surface points observed at least once, after each frame (0..1)",
            "auc": auc}))
