"""Readers and training datasets for generated seed folders (no bpy; torch optional).

    from datasets import Scene, FrameDataset
    scene = Scene("output/seed_000000")
    frame = scene.frames[0]            # rgb, depth, label, instance, K, pose, timestamp
    ds = FrameDataset(["output/seed_000000", "output/seed_000137"])
    scans = ScanDataset("output/seed_000000", sensor="os1-128")   # with python -m generator --lidar os1-128
"""

from .scene import DatasetError, Frame, Scene, Sequence
from .scans import ScanDataset
from .tasks import ClipDataset, FrameDataset, PointCloudDataset
from .transforms import Compose, Crop, Resize, ToLinear, Undistort, linear_to_srgb, srgb_to_linear

__all__ = ["Scene", "Sequence", "Frame", "DatasetError", "FrameDataset", "ClipDataset", "PointCloudDataset", "ScanDataset",
           "Crop", "Resize", "ToLinear", "Undistort", "Compose", "srgb_to_linear", "linear_to_srgb"]
