"""Offline scoring of reconstructions and explorations (no bpy): ``python -m evaluation``
or the functions below. Metric definitions: docs/evaluation.md."""

from .api import colour_ply, load_gt_cloud, score_coverage, score_reconstruction, score_tracks
from .coverage import CoverageScorer, Poses, coverage_auc, read_poses
from .inputs import Cloud, InputError, read_cloud
from .metrics import reconstruction_metrics, voxel_downsample
from .tracking import tapvid_metrics

__all__ = ["score_reconstruction", "score_coverage", "score_tracks", "tapvid_metrics", "reconstruction_metrics", "voxel_downsample", "coverage_auc",
           "CoverageScorer", "Poses", "read_poses", "read_cloud", "load_gt_cloud", "colour_ply", "Cloud", "InputError"]
