"""A diversity report of many seeds' site plans (bpy-free, nothing rendered):
``python -m generator.scene --survey 0-99 --out DIR`` writes ``DIR/survey.json`` (per seed and
in total) and ``DIR/survey.md`` (the totals as tables); with ``--previews`` also each seed's
preview, its colour and a contact sheet (:mod:`.survey_previews`, which builds the sites in
Blender). docs/scenes.md, "Survey".

Per seed: its buildings (type, levels built, planned and enclosed, height), the asset kinds and how many of each,
the objects per taxonomy class (the plan's parts with a mesh: the site's Blender objects but
the ground and fence), the context (what surrounds the site), the season, the ground's surface and road,
the relief's digs, the weather and the sun's elevation, and what found no room. In total:
for each of these, on how many seeds each value occurs (and, for the kinds and classes, how
many there are in all), and on how many seeds each class of MOCS and ACID that fits a
building site appears (:data:`DETECTOR_CLASSES`: a mixer truck is a concrete mixer).
"""

from __future__ import annotations

import json
import re
from collections import Counter
from pathlib import Path

from .site import plan_site, site_params

MAX_SURVEY = 10_000  # seeds in one report


def _holds(label: str):
    return lambda r: r["objects_per_class"].get(label, 0) > 0


# the classes of MOCS and ACID that fit a building site, as a seed's record shows them
DETECTOR_CLASSES = {
    "worker": _holds("Worker"), "tower crane": _holds("Crane"), "mobile crane": _holds("MobileCrane"),
    "excavator": _holds("Excavator"), "truck (dump)": lambda r: "dump" in r["truck_bodies"],
    "concrete mixer": lambda r: "mixer" in r["truck_bodies"], "pump truck": _holds("PumpTruck"),
    "roller": _holds("Roller"), "loader": _holds("Loader"), "pile driver": _holds("PileDriver"),
}


def parse_seeds(text: str) -> list[int]:
    """``"A-B"`` (inclusive) or ``"A"``: the seeds of a survey; ValueError naming the form."""
    m = re.fullmatch(r"\s*(\d+)\s*(?:-\s*(\d+)\s*)?", text)
    if m is None:
        raise ValueError(f"--survey takes a seed or a range of seeds like 0-99, got {text!r}")
    first, last = int(m.group(1)), int(m.group(2) or m.group(1))
    if last < first:
        raise ValueError(f"--survey {text}: the range ends before it starts; write it low-high, e.g. {last}-{first}")
    if last - first + 1 > MAX_SURVEY:
        raise ValueError(f"--survey {text}: {last - first + 1} seeds; survey at most {MAX_SURVEY} at once")
    return list(range(first, last + 1))


def seed_record(seed: int, preset: str = "medium", **overrides) -> dict:
    """What the plan of ``seed`` holds (module docstring), JSON-ready: site.json's summary of
    the plan, plus the objects per class."""
    plan = plan_site(seed, site_params(preset, **overrides))
    summary = plan.summary()
    classes = Counter(part.label for p in plan.placed for part in p.asset.parts if part.mesh is not None)
    return {"seed": seed, "buildings": summary["buildings"], "kinds": dict(sorted(summary["assets"].items())),
            "objects_per_class": dict(sorted(classes.items())), "ground": summary["ground"],
            "digs": [d["kind"] for d in summary["relief"]["digs"]], "weather": summary["weather"]["name"],
            "context": summary["context"], "season": summary["weather"]["season"],
            "truck_bodies": sorted(p.asset.info["kind"] for p in plan.placed if p.asset.kind == "Truck"),
            "sun_elevation_deg": round(summary["weather"]["sun_elevation_deg"], 2),
            "skipped": dict(sorted(summary["skipped"].items()))}


def totals(records: list[dict]) -> dict:
    """Seeds per value of each categorical field, and per kind and class: seeds holding one, count in all."""
    def seeds_with(values):
        return dict(sorted(Counter(values).items(), key=lambda kv: (-kv[1], str(kv[0]))))

    out = {"seeds": len(records),
           "surface": seeds_with(r["ground"]["surface"] for r in records),
           "road": seeds_with(r["ground"]["road"] for r in records),
           "weather": seeds_with(r["weather"] for r in records),
           "context": seeds_with(r["context"] for r in records),
           "season": seeds_with(r["season"] for r in records),
           "digs": seeds_with(d for r in records for d in sorted(set(r["digs"]))),
           "buildings_per_site": seeds_with(len(r["buildings"]) for r in records),
           "building_type": seeds_with(t for r in records for t in sorted({b["type"] for b in r["buildings"]}))}
    for field in ("kinds", "objects_per_class"):
        out[field] = {name: {"seeds": sum(1 for r in records if r[field].get(name)),
                             "total": sum(r[field].get(name, 0) for r in records)}
                      for name in sorted({n for r in records for n in r[field]})}
    out["detector_classes"] = {name: sum(1 for r in records if has(r)) for name, has in DETECTOR_CLASSES.items()}
    sun = sorted(r["sun_elevation_deg"] for r in records)
    out["sun_elevation_deg"] = {"min": sun[0], "median": sun[len(sun) // 2], "max": sun[-1]}
    return out


def markdown(total: dict, preset: str) -> str:
    """The totals as Markdown tables."""
    n = total["seeds"]
    lines = [f"# Survey of {n} seeds ({preset})", ""]
    for field in ("context", "season", "surface", "road", "weather", "digs", "buildings_per_site", "building_type"):
        lines += [f"| {field} | seeds | share |", "|---|---|---|"]
        lines += [f"| {value} | {count} | {count / n:.0%} |" for value, count in total[field].items()]
        lines.append("")
    for field in ("kinds", "objects_per_class"):
        lines += [f"| {field} | seeds holding one | share | in all |", "|---|---|---|---|"]
        lines += [f"| {name} | {v['seeds']} | {v['seeds'] / n:.0%} | {v['total']} |" for name, v in total[field].items()]
        lines.append("")
    lines += ["| MOCS / ACID class | seeds holding one | share |", "|---|---|---|"]
    lines += [f"| {name} | {count} | {count / n:.0%} |" for name, count in total["detector_classes"].items()]
    lines.append("")
    s = total["sun_elevation_deg"]
    lines.append(f"Sun elevation: {s['min']}-{s['max']} degrees, median {s['median']}.")
    if "preview_colour_spread" in total:
        c = total["preview_colour_spread"]
        lines += ["", f"Preview colour spread (std over seeds of each channel's mean, 8-bit sRGB in [0, 1]): "
                      f"R {c['r']:.4f}, G {c['g']:.4f}, B {c['b']:.4f}, mean {c['mean']:.4f}; previews in "
                      "previews/, contact_sheet.png."]
    return "\n".join(lines) + "\n"


def write_survey(seeds: list[int], out: Path, preset: str = "medium", progress=None, previews: bool = False,
                 **overrides) -> dict:
    """Plan every seed, write ``survey.json`` and ``survey.md`` into ``out``; the totals.
    ``previews``: also build each seed and keep its preview, colour and a contact sheet
    (imports bpy). ``progress``: wraps an iteration over the seeds (a tqdm), if given."""
    records = [seed_record(s, preset, **overrides) for s in (progress(seeds) if progress else seeds)]
    total = totals(records)
    out.mkdir(parents=True, exist_ok=True)
    if previews:
        from .survey_previews import colour_spread, contact_sheet, preview_colour, preview_seeds

        kept = preview_seeds(seeds, out, preset, progress, **overrides)
        for r in records:
            r["preview_mean_rgb"] = preview_colour(kept[r["seed"]])
        total["preview_colour_spread"] = colour_spread([r["preview_mean_rgb"] for r in records])
        contact_sheet([(s, kept[s]) for s in seeds], out / "contact_sheet.png")
    (out / "survey.json").write_text(json.dumps({"preset": preset, "overrides": overrides, "totals": total,
                                                 "seeds": records}, indent=1) + "\n")
    (out / "survey.md").write_text(markdown(total, preset))
    return total
