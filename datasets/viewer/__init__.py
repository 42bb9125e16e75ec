"""Rerun recordings of generated seeds and of evaluation results (``python -m datasets.view``;
docs/viewer.md). rerun-sdk is imported only when a recording is made."""

from .common import MAX_POINTS, UNLABELLED_ID, subsample_stride, subsampled_count

__all__ = ["MAX_POINTS", "UNLABELLED_ID", "subsample_stride", "subsampled_count", "record_seed"]


def record_seed(seed_folder, out, trajectories=None, max_points: int = MAX_POINTS, progress=None) -> dict:
    """Write ``out`` (.rrd) for a seed folder; returns the counts logged (see seed.record_scene)."""
    from datasets import Scene

    from .common import recording_file
    from .seed import blueprint, frame_rate, record_scene

    scene = Scene(seed_folder)
    kinds = trajectories or scene.trajectories
    with recording_file(out, f"seed_{scene.seed:06d}", blueprint(kinds, frame_rate(scene[kinds[0]]))) as rec:
        return record_scene(rec, scene, kinds, max_points, progress)
