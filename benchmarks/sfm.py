"""Structure-from-motion on a generated seed's RGB with pycolmap's own pipeline (issue #38):
what a user who runs COLMAP on our frames gets.

For SEED_FOLDER (a seed of the main job, e.g. output/seed_000000), on the RGB PNGs of its
trajectories together (default: every trajectory; the main job's orbit and spline are 80
frames):

1. SfM, no intrinsics given: pycolmap.extract_features (SIFT on the CPU, default options,
   one camera shared by all frames: ``CameraMode.SINGLE``, COLMAP's default SIMPLE_RADIAL
   model), match_exhaustive and incremental_mapping with their default options. Reported:
   the models, the frames in the largest, its self-calibrated focal length against the
   truth (relative error), and its camera centres after a similarity alignment (Umeyama,
   least squares) to the true ones: median and largest error as a share of the scene's
   extent (the diagonal of the box holding every true camera centre of the seed's frames).
2. Triangulation with the true poses and intrinsics: the seed's exported COLMAP cameras and
   poses (each trajectory's sparse/0), the keypoints and verified matches of step 1, and
   pycolmap.triangulate_points with default options. Reported: the points, the share of
   them within 0.1 m of the scene's surface (distance to ground_truth/mesh.ply, Open3D), and
   within what 2 pixels span at the nearest camera that sees each point.

Usage: .venv/bin/python benchmarks/sfm.py SEED_FOLDER [--trajectories orbit spline] [--json FILE]
       [--work DIR] (the COLMAP database and models; default: a temporary folder)
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ON_SURFACE_M = 0.1


def umeyama(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """(scale, R, t) minimising sum |s R src + t - dst|^2 over the rows (Umeyama 1991)."""
    mu_s, mu_d = src.mean(axis=0), dst.mean(axis=0)
    a, b = src - mu_s, dst - mu_d
    u, d, vt = np.linalg.svd(b.T @ a / len(src))
    sign = np.eye(3)
    if np.linalg.det(u) * np.linalg.det(vt) < 0:
        sign[2, 2] = -1.0
    r = u @ sign @ vt
    scale = float(np.trace(np.diag(d) @ sign) / a.var(axis=0).sum())
    return scale, r, mu_d - scale * r @ mu_s


def gather_images(seed: Path, trajectories: list[str], images: Path) -> dict[str, tuple[str, str]]:
    """Copies each trajectory's rgb_NNNNNN.png to images/<trajectory>_rgb_NNNNNN.png; returns
    new name -> (trajectory, its name in the trajectory's COLMAP model)."""
    images.mkdir(parents=True)
    names = {}
    for traj in trajectories:
        for png in sorted((seed / traj).glob("rgb_*.png")):
            name = f"{traj}_{png.name}"
            shutil.copy(png, images / name)
            names[name] = (traj, png.name)
    return names


def true_model(seed: Path, names: dict[str, tuple[str, str]], db):
    """A pycolmap Reconstruction holding the true camera (the seed's exported one, also
    written over the database's self-calibrated one) and every image at its true pose, with
    the database's image ids and keypoints."""
    import pycolmap

    models = {t: pycolmap.Reconstruction(str(seed / t / "sparse" / "0")) for t in {t for t, _ in names.values()}}
    camera = next(iter(next(iter(models.values())).cameras.values()))
    true_camera = pycolmap.Camera(model=camera.model_name, width=camera.width, height=camera.height,
                                  params=camera.params, camera_id=1)
    db.update_camera(true_camera)  # the triangulator reads the database's camera too
    rec = pycolmap.Reconstruction()
    rec.add_camera_with_trivial_rig(true_camera)
    for image in db.read_all_images():
        traj, original = names[image.name]
        truth = models[traj].find_image_with_name(original)
        keypoints = db.read_keypoints(image.image_id)[:, :2].astype(np.float64)
        rec.add_image_with_trivial_frame(pycolmap.Image(name=image.name, keypoints=keypoints, camera_id=1,
                                                        image_id=image.image_id), truth.cam_from_world())
    return rec


def true_centres(seed: Path, names: dict[str, tuple[str, str]]) -> dict[str, np.ndarray]:
    """Image name -> its true camera centre (world metres)."""
    import pycolmap

    out = {}
    for traj in {t for t, _ in names.values()}:
        model = pycolmap.Reconstruction(str(seed / traj / "sparse" / "0"))
        for image in model.images.values():
            out[f"{traj}_{image.name}"] = np.asarray(image.projection_center())
    return out


def surface_distances(seed: Path, points: np.ndarray) -> np.ndarray:
    """Distance (metres) of each point to the seed's ground-truth mesh."""
    from exporters.ply import read_ply
    from generator.geometry.o3d import import_open3d

    o3d = import_open3d()
    mesh = read_ply(seed / "ground_truth" / "mesh.ply")
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.points.astype(np.float32)), o3d.core.Tensor(mesh.faces.astype(np.uint32)))
    return scene.compute_distance(o3d.core.Tensor(points.astype(np.float32))).numpy()


def sfm_figures(seed: Path, trajectories: list[str], work: Path) -> dict:
    import pycolmap

    pycolmap.logging.minloglevel = 2  # COLMAP's progress lines: warnings and errors only

    names = gather_images(seed, trajectories, work / "images")
    db_path = work / "database.db"
    timings = {}
    t0 = time.perf_counter()
    pycolmap.extract_features(db_path, work / "images", camera_mode=pycolmap.CameraMode.SINGLE,
                              device=pycolmap.Device.cpu)
    timings["extract_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    pycolmap.match_exhaustive(db_path, device=pycolmap.Device.cpu)
    timings["match_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    models = pycolmap.incremental_mapping(db_path, work / "images", work / "sparse")
    timings["map_s"] = time.perf_counter() - t0
    centres = true_centres(seed, names)
    all_true = np.array(list(centres.values()))
    extent = float(np.linalg.norm(all_true.max(axis=0) - all_true.min(axis=0)))
    truth_f = float(next(iter(pycolmap.Reconstruction(str(seed / trajectories[0] / "sparse" / "0")).cameras.values()))
                    .focal_length_x)
    result = {"frames": len(names), "models": [m.num_reg_images() for m in models.values()], "extent_m": extent,
              "true_focal_px": truth_f, "timings": timings}
    if models:
        best = max(models.values(), key=lambda m: m.num_reg_images())
        estimated = {best.image(i).name: np.asarray(best.image(i).projection_center()) for i in best.reg_image_ids()}
        src = np.array([estimated[n] for n in estimated])
        dst = np.array([centres[n] for n in estimated])
        s, r, t = umeyama(src, dst)
        err = np.linalg.norm((s * (r @ src.T)).T + t - dst, axis=1) / extent
        focal = float(next(iter(best.cameras.values())).focal_length)
        result |= {"largest_model_frames": best.num_reg_images(), "largest_model_share": best.num_reg_images() / len(names),
                   "focal_px": focal, "focal_rel_error": abs(focal - truth_f) / truth_f,
                   "centre_error_median_of_extent": float(np.median(err)), "centre_error_max_of_extent": float(err.max()),
                   "sfm_points": best.num_points3D()}
    db = pycolmap.Database.open(str(db_path))
    try:
        rec = true_model(seed, names, db)
    finally:
        db.close()
    (work / "true").mkdir()
    t0 = time.perf_counter()
    tri = pycolmap.triangulate_points(rec, db_path, work / "images", work / "true")
    timings["triangulate_s"] = time.perf_counter() - t0
    points = np.array([p.xyz for p in tri.points3D.values()]).reshape(-1, 3)
    d = surface_distances(seed, points) if len(points) else np.zeros(0)
    # what 2 pixels span at the nearest camera that sees each point: the accuracy its
    # observations allow (0.1 m is 0.65 px at the orbit's 55 m)
    centre = {i: np.asarray(tri.image(i).projection_center()) for i in tri.reg_image_ids()}
    nearest = np.array([min(float(np.linalg.norm(centre[e.image_id] - p.xyz)) for e in p.track.elements)
                        for p in tri.points3D.values()])
    two_px = 2.0 * nearest / truth_f
    result |= {"true_pose_points": len(points),
               "true_pose_points_within_0.1m": float((d <= ON_SURFACE_M).mean()) if len(d) else float("nan"),
               "true_pose_points_within_2px": float((d <= two_px).mean()) if len(d) else float("nan"),
               "true_pose_points_median_distance_m": float(np.median(d)) if len(d) else float("nan"),
               "true_pose_points_median_range_m": float(np.median(nearest)) if len(d) else float("nan")}
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seed", type=Path, help="a seed folder of the main job (e.g. output/seed_000000)")
    ap.add_argument("--trajectories", nargs="+", default=None, help="trajectories to use together (default: all)")
    ap.add_argument("--json", type=Path, help="write the figures to this JSON file")
    ap.add_argument("--work", type=Path, help="folder for the COLMAP database and models (default: temporary)")
    args = ap.parse_args(argv)
    if not (args.seed / "labels.json").is_file():
        print(f"error: {args.seed} is not a seed folder (no labels.json); give one of the main job's seeds",
              file=sys.stderr)
        return 2
    trajs = args.trajectories or sorted(p.name for p in args.seed.iterdir() if (p / "sparse" / "0").is_dir())
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        if args.work is not None and work.exists() and any(work.iterdir()):
            print(f"error: --work {work} is not empty; give a new folder", file=sys.stderr)
            return 2
        figures = sfm_figures(args.seed, trajs, work)
    print(json.dumps(figures, indent=1))
    if args.json:
        args.json.write_text(json.dumps({"seed": str(args.seed), "trajectories": trajs} | figures, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
