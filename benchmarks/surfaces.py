"""What the cameras see (issue #38): texture and SIFT figures of a generated seed's RGB.

For every trajectory of SEED_FOLDER (a seed of the main job, e.g. output/seed_000000):

- ``textureless_ground`` / ``textureless_surfaces``: the share of `Ground` pixels / of all
  pixels with a surface (label other than none, i.e. not sky) that lie in a 16x16 patch
  (non-overlapping, from the top-left corner) whose intensity standard deviation is below
  2/255 (intensity: the mean of the display PNG's R, G and B, in [0, 1]);
- ``sift_per_10k_ground``: SIFT keypoints (pycolmap's extractor with its default options, on
  the 8-bit grey image as COLMAP reads it) whose pixel is a `Ground` pixel, per 10,000
  `Ground` pixels;
- ``sift_per_10k_surfaces``: the same over every surface pixel.

Usage: .venv/bin/python benchmarks/surfaces.py SEED_FOLDER [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from PIL import Image

PATCH = 16
FLAT = 2 / 255  # intensity standard deviation below which a patch has no texture


def textureless(intensity: np.ndarray) -> np.ndarray:
    """(H, W) bool: the pixel lies in a PATCH x PATCH patch whose intensity standard deviation
    is below FLAT (pixels past the last whole patch: False)."""
    h, w = intensity.shape
    ph, pw = h // PATCH, w // PATCH
    blocks = intensity[:ph * PATCH, :pw * PATCH].reshape(ph, PATCH, pw, PATCH)
    flat = blocks.std(axis=(1, 3)) < FLAT
    out = np.zeros((h, w), dtype=bool)
    out[:ph * PATCH, :pw * PATCH] = np.repeat(np.repeat(flat, PATCH, axis=0), PATCH, axis=1)
    return out


def frame_figures(rgb_png: Path, label_png: Path, ground: int, sift) -> dict[str, float]:
    """Counts of one frame: pixels, textureless pixels and keypoints, on ground and surfaces."""
    with Image.open(rgb_png) as im:
        rgb8 = im.convert("RGB")
    with Image.open(label_png) as im:
        label = np.asarray(im, dtype=np.int64) - 1  # PNG: label id + 1, 0 = none
    flat = textureless(np.asarray(rgb8, dtype=np.float32).mean(axis=2) / 255.0)
    grey = np.asarray(rgb8.convert("L"))  # as COLMAP reads the image
    keypoints = np.array([(k.x, k.y) for k in sift.extract_from_uint8_array(grey)[0]]).reshape(-1, 2)
    cols = np.clip(np.floor(keypoints[:, 0]).astype(int), 0, label.shape[1] - 1)
    rows = np.clip(np.floor(keypoints[:, 1]).astype(int), 0, label.shape[0] - 1)
    at = label[rows, cols]
    masks = {"ground": label == ground, "surfaces": label >= 0}
    out = {}
    for name, mask in masks.items():
        out[f"{name}_pixels"] = int(mask.sum())
        out[f"{name}_flat"] = int((flat & mask).sum())
    out["ground_keypoints"] = int((at == ground).sum())
    out["surfaces_keypoints"] = int((at >= 0).sum())
    return out


def seed_figures(seed: Path) -> dict[str, dict[str, float]]:
    import pycolmap

    labels = json.loads((seed / "labels.json").read_text())
    ground = labels.index("Ground")
    sift = pycolmap.FeatureExtractor.create(device=pycolmap.Device.cpu)
    result = {}
    for traj in sorted(p for p in seed.iterdir() if p.is_dir() and any(p.glob("rgb_*.png"))):
        total: dict[str, int] = {}
        frames = sorted(traj.glob("rgb_*.png"))
        with Image.open(frames[0]) as im:
            pixels = im.width * im.height
        for rgb in frames:
            for k, v in frame_figures(rgb, traj / rgb.name.replace("rgb_", "label_"), ground, sift).items():
                total[k] = total.get(k, 0) + v
        share = lambda a, b: total[a] / total[b] if total[b] else float("nan")  # noqa: E731
        result[traj.name] = {
            "frames": len(frames),
            "ground_share_of_pixels": total["ground_pixels"] / (len(frames) * pixels),
            "textureless_ground": share("ground_flat", "ground_pixels"),
            "textureless_surfaces": share("surfaces_flat", "surfaces_pixels"),
            "sift_per_10k_ground": 1e4 * share("ground_keypoints", "ground_pixels"),
            "sift_per_10k_surfaces": 1e4 * share("surfaces_keypoints", "surfaces_pixels"),
        }
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seed", type=Path, help="a seed folder of the main job (e.g. output/seed_000000)")
    ap.add_argument("--json", type=Path, help="write the figures to this JSON file")
    args = ap.parse_args(argv)
    if not (args.seed / "labels.json").is_file():
        print(f"error: {args.seed} is not a seed folder (no labels.json); give one of the main job's seeds",
              file=sys.stderr)
        return 2
    figures = seed_figures(args.seed)
    print(f"{'trajectory':<12}{'frames':>7}{'ground':>8}{'flat ground':>13}{'flat surfaces':>15}"
          f"{'SIFT/10k ground':>17}{'SIFT/10k surfaces':>19}")
    for name, f in figures.items():
        print(f"{name:<12}{f['frames']:>7}{f['ground_share_of_pixels']:>8.0%}{f['textureless_ground']:>13.1%}"
              f"{f['textureless_surfaces']:>15.1%}{f['sift_per_10k_ground']:>17.1f}{f['sift_per_10k_surfaces']:>19.1f}")
    if args.json:
        args.json.write_text(json.dumps({"seed": str(args.seed), "trajectories": figures}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
