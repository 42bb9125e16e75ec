"""Human-readable outputs: terminal tables and the coverage-curve PNG."""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from exporters.write_guard import png_info, signed_json


def reconstruction_table(results: dict) -> str:
    m, p = results["metrics"], results["parameters"]
    o = m.get("observable") or {"available": False, "note": "no observable-only figures in these results"}
    has = o.get("available", False) and "completeness" in o
    lines = [f"reconstruction: {results['inputs']['pred_points_scored']:,} predicted vs "
             f"{results['inputs']['gt_points_scored']:,} ground-truth points, tau = {p['tau']} m"
             + (f", voxel {p['voxel']} m" if p["voxel"] else "") + (", cropped to GT bounds" if p["crop"] else ""),
             "", f"{'metric':<42}{'all GT':>12}{'observable':>12}  unit"]

    def row(name, value, unit="", observable=None):
        obs = f"{observable:>12.4f}" if observable is not None else f"{'':>12}"
        lines.append(f"{name:<42}{value:>12.4f}{obs}  {unit}")

    def ob(key, group=None):
        if not has:
            return None
        src = o.get(group) if group else o
        return None if src is None else src.get(key)

    row("accuracy (pred -> GT, mean)", m["accuracy"], "m")
    row("completeness (GT -> pred, mean)", m["completeness"], "m", ob("completeness"))
    row("Chamfer-L1 (mean of both)", m["chamfer_l1"], "m", ob("chamfer_l1"))
    row("Chamfer-L2 (mean of both, squared)", m["chamfer_l2"], "m^2", ob("chamfer_l2"))
    row(f"precision @ {p['tau']} m", m["precision"])
    row(f"recall @ {p['tau']} m", m["recall"], "", ob("recall"))
    row(f"F-score @ {p['tau']} m", m["fscore"], "", ob("fscore"))
    if "semantic" in m:
        s = m["semantic"]
        row("Semantic Chamfer pred -> GT", s["semantic_chamfer_pred_to_gt"])
        row("Semantic Chamfer GT -> pred", s["semantic_chamfer_gt_to_pred"], "", ob("semantic_chamfer_gt_to_pred", "semantic"))
        row("mIoU (on GT points)", s["miou"], "", ob("miou", "semantic"))
        row("mIoU (paper: on pred points within tau)", s["miou_paper"])
        if s["classes_missing_from_pred"]:
            lines.append(f"classes missing from the prediction: {', '.join(s['classes_missing_from_pred'])}")
    if has:
        lines.append(f"observable: {o['gt_points']:,} of the ground-truth points ({o['share_of_gt']:.1%}) can be seen "
                     "from the camera spawn volume; figures over predicted points are the same for both")
    else:
        lines.append(f"observable: not available ({o.get('note', 'no mask')})")
    sweep_obs = o.get("sweep") if has else None
    lines += ["", "sweep:   tau    precision  recall  F-score" + ("   recall (obs)  F-score (obs)" if sweep_obs else "")]
    for k, e in enumerate(m["sweep"]):
        line = f"       {e['tau']:>6.3f}   {e['precision']:>7.4f}  {e['recall']:>6.4f}  {e['fscore']:>7.4f}"
        if sweep_obs:
            line += f"   {sweep_obs[k]['recall']:>12.4f}  {sweep_obs[k]['fscore']:>13.4f}"
        lines.append(line)
    if "paper" in m:
        lines += ["", "paper-compatible (one direction, Manhattan norm):",
                  f"  Chamfer-L1 pred -> GT {m['paper']['chamfer_l1_manhattan_pred_to_gt']:.4f} m, "
                  f"GT -> pred {m['paper']['chamfer_l1_manhattan_gt_to_pred']:.4f} m"]
    if "semantic" in m and m["semantic"]["iou"]:
        lines += ["", "IoU per class (GT points): " + ", ".join(f"{k} {v:.3f}" for k, v in m["semantic"]["iou"].items())]
    return "\n".join(lines)


def coverage_table(results: dict) -> str:
    c = results["coverage"]
    marks = sorted({0, len(c) // 4, len(c) // 2, 3 * len(c) // 4, len(c) - 1})
    o = results.get("observable") or {"available": False, "note": "no observable-only figures in these results"}
    if o.get("available"):
        co = o["coverage"]
        obs_lines = [f"  over the {o['num_points']:,} observable points ({o['share_of_points']:.1%}, seen from "
                     "some point of the spawn volume):",
                     f"  AUC            {o['auc']:.4f}",
                     f"  final coverage {o['final_coverage']:.4f}",
                     "  curve          " + ", ".join(f"pose {i}: {co[i]:.4f}" for i in marks)]
    else:
        obs_lines = [f"  observable-only coverage: not available ({o.get('note', 'no mask')})"]
    return "\n".join([
        f"coverage: {results['num_poses']} poses, {results['num_points']:,} ground-truth surface points, "
        f"visible within {results['parameters']['far']:g} m (planar depth)",
        f"  AUC            {results['auc']:.4f}",
        f"  final coverage {results['final_coverage']:.4f}",
        "  curve          " + ", ".join(f"pose {i}: {c[i]:.4f}" for i in marks),
    ] + obs_lines + ([f"  note: {results['parameters']['poses_outside_the_animation']} poses fall after the recorded animation "
          "and see its last frame (use --frames first for a static scene)"]
         if results["parameters"].get("poses_outside_the_animation") else []))


def tracks_table(results: dict) -> str:
    m = results["metrics"]
    return "\n".join([
        f"tracks: {m['num_queries']} queries x {m['num_frames']} frames, query mode {m['query_mode']}"
        + (f", positions scaled to {m['resize_to'][0]}x{m['resize_to'][1]}" if m["resize_to"] else ""),
        f"  occlusion accuracy   {m['occlusion_accuracy']:.4f}",
        f"  <delta avg           {m['average_pts_within']:.4f}   (" + ", ".join(f"<{k} px {v:.3f}" for k, v in m["pts_within"].items()) + ")",
        f"  Average Jaccard      {m['average_jaccard']:.4f}   (" + ", ".join(f"{k} px {v:.3f}" for k, v in m["jaccard"].items()) + ")",
    ])


def write_atomic(path: str | Path, data: bytes) -> Path:
    """Write through a temporary file renamed into place (never a half-written file)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_bytes(data)
        tmp.replace(path)
    finally:  # no temporary file left behind when the write or the rename fails
        tmp.unlink(missing_ok=True)
    return path


def write_json(path: str | Path, results: dict) -> Path:
    """``results`` as JSON, signed first (exporters.write_guard: a later run may replace it)."""
    return write_atomic(path, json.dumps(signed_json(results), indent=1).encode())


def coverage_plot(path: str | Path, curves: dict[str, np.ndarray], title: str = "coverage") -> Path:
    """A PNG of coverage curves (x: pose index, y: coverage 0..1), drawn with PIL."""
    W, H, left, right, top, bottom = 640, 400, 60, 20, 30, 45
    img = Image.new("RGB", (W, H), "white")
    d = ImageDraw.Draw(img)
    x0, x1, y0, y1 = left, W - right, H - bottom, top
    n = max(len(c) for c in curves.values())
    d.rectangle([x0, y1, x1, y0], outline=(0, 0, 0))
    for k in range(6):
        y = y0 + (y1 - y0) * k / 5
        d.line([(x0, y), (x1, y)], fill=(225, 225, 225))
        d.text((x0 - 30, y - 6), f"{k / 5:.1f}", fill=(0, 0, 0))
    for k in range(5):
        x = x0 + (x1 - x0) * k / 4
        d.text((x - 8, y0 + 6), f"{round((n - 1) * k / 4)}", fill=(0, 0, 0))
    d.text((W // 2 - 20, H - 20), "pose", fill=(0, 0, 0))
    d.text((x0, 8), title, fill=(0, 0, 0))
    colours = [(31, 119, 180), (214, 39, 40), (44, 160, 44), (255, 127, 14), (148, 103, 189)]
    for j, (name, c) in enumerate(curves.items()):
        c = np.asarray(c, float)
        xs = x0 + (x1 - x0) * np.arange(len(c)) / max(n - 1, 1)
        ys = y0 + (y1 - y0) * np.clip(c, 0, 1)
        colour = colours[j % len(colours)]
        if len(c) > 1:
            d.line(list(zip(xs, ys)), fill=colour, width=2)
        else:
            d.ellipse([xs[0] - 2, ys[0] - 2, xs[0] + 2, ys[0] + 2], fill=colour)
        d.text((x1 - 200, y1 + 8 + 14 * j), name, fill=colour)
    buffer = io.BytesIO()
    img.save(buffer, format="PNG", pnginfo=png_info())
    return write_atomic(path, buffer.getvalue())
