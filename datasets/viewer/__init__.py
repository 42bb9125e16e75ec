"""Rerun recordings of generated seeds and of evaluation results (``python -m datasets.view``;
docs/viewer.md). rerun-sdk is imported only when a recording is made."""

from .common import MAX_POINTS, UNLABELLED_ID, subsample_stride, subsampled_count

__all__ = ["MAX_POINTS", "UNLABELLED_ID", "subsample_stride", "subsampled_count", "record_seed"]


def record_seed(seed_folder, out, trajectories=None, max_points: int = MAX_POINTS, progress=None) -> dict:
    """Write ``out`` (.rrd) for a seed folder (or a stage ``SEED/phase_K`` of a timeline seed);
    returns the counts logged (see seed.record_scene)."""
    from .common import recording_file
    from .seed import blueprint, open_scene, record_scene, recording_id

    scene = open_scene(seed_folder)
    kinds = trajectories or scene.trajectories
    with recording_file(out, recording_id(scene), blueprint(scene, kinds)) as rec:
        return record_scene(rec, scene, kinds, max_points, progress)
