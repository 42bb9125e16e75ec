"""The diversity report (generator/scene/survey.py, `python -m generator.scene --survey`):
its per-seed records are the plans' contents, its totals add them up, bad ranges are refused."""

import json
import subprocess
import sys
from collections import Counter

import pytest

from conftest import ROOT, assert_refused
from generator.scene.site import plan_site, site_params
from generator.scene.survey import parse_seeds


def test_the_survey_reports_each_plan_and_adds_them_up(tmp_path):
    r = subprocess.run([sys.executable, "-m", "generator.scene", "--survey", "3-6", "--preset", "small",
                        "--out", str(tmp_path / "s")], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads((tmp_path / "s" / "survey.json").read_text())
    records, totals = report["seeds"], report["totals"]
    assert [x["seed"] for x in records] == [3, 4, 5, 6] and totals["seeds"] == 4
    plan = plan_site(5, site_params("small"))  # the record is the plan, read anew
    record = records[2]
    assert record["kinds"] == dict(Counter(p.asset.kind for p in plan.placed))
    assert record["ground"] == {"surface": plan.ground.surface, "road": plan.ground.road}
    assert record["weather"] == plan.weather.name and record["digs"] == [d.kind for d in plan.relief.digs]
    assert len(record["buildings"]) == sum(p.asset.kind == "Building" for p in plan.placed)
    assert record["context"] == plan.context.name and record["season"] == plan.weather.season
    mixers = sum(p.asset.kind == "Truck" and p.asset.info["kind"] == "mixer" for p in plan.placed)
    assert sorted(record["truck_bodies"]).count("mixer") == mixers
    for name, count in totals["detector_classes"].items():  # a seed holding one, per MOCS / ACID class
        assert 0 <= count <= 4, name
    assert totals["detector_classes"]["tower crane"] == sum(1 for x in records if x["objects_per_class"].get("Crane"))
    assert sum(totals["context"].values()) == 4 and sum(totals["season"].values()) == 4
    for kind, v in totals["kinds"].items():
        assert v["total"] == sum(x["kinds"].get(kind, 0) for x in records)
        assert v["seeds"] == sum(1 for x in records if x["kinds"].get(kind))
    assert sum(totals["weather"].values()) == 4 and sum(totals["surface"].values()) == 4
    assert "| weather | seeds | share |" in (tmp_path / "s" / "survey.md").read_text()


def test_bad_survey_ranges_are_one_line_and_exit_2(tmp_path):
    assert parse_seeds("7") == [7] and parse_seeds(" 2-4 ") == [2, 3, 4]
    for bad, words in (("5-2", "low-high"), ("a-b", "a range of seeds like 0-99"), ("0-20000", "at most")):
        with pytest.raises(ValueError, match=words):
            parse_seeds(bad)
    assert_refused(subprocess.run([sys.executable, "-m", "generator.scene", "--survey", "9-1", "--out", str(tmp_path / "x")],
                                  capture_output=True, text=True, cwd=ROOT), "--survey 9-1", "1-9")
    assert_refused(subprocess.run([sys.executable, "-m", "generator.scene", "--out", str(tmp_path / "y")],
                                  capture_output=True, text=True, cwd=ROOT), "--seed", "--survey")


def test_survey_previews_are_the_sites_previews_with_their_colours(tmp_path):
    """--previews keeps each seed's own preview (the same bytes as building that seed alone),
    its mean colour, the spread of the colours over the seeds and a contact sheet of them."""
    import numpy as np
    from PIL import Image

    from generator.scene import build_site

    r = subprocess.run([sys.executable, "-m", "generator.scene", "--survey", "3-4", "--preset", "small", "--previews",
                        "--out", str(tmp_path / "s")], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads((tmp_path / "s" / "survey.json").read_text())
    alone = build_site(4, "small", tmp_path / "alone", preview=True)
    kept = tmp_path / "s" / "previews" / "seed_000004.png"
    assert kept.read_bytes() == alone.preview.read_bytes()
    means = []
    for record in report["seeds"]:
        rgb = np.asarray(Image.open(tmp_path / "s" / "previews" / f"seed_{record['seed']:06d}.png").convert("RGB")) / 255.0
        means.append(rgb.reshape(-1, 3).mean(axis=0))
        assert np.allclose(record["preview_mean_rgb"], means[-1], atol=1e-12)
    spread = report["totals"]["preview_colour_spread"]
    assert np.allclose([spread["r"], spread["g"], spread["b"]], np.std(means, axis=0), atol=1e-12) and spread["mean"] > 0
    with Image.open(tmp_path / "s" / "contact_sheet.png") as sheet:
        assert sheet.size == (4 * 240, 160)
        second = np.asarray(sheet.convert("RGB"))[20:160, 260:480].astype(float)
    thumb = np.asarray(Image.open(kept).convert("RGB").resize((240, 160), Image.Resampling.LANCZOS))[20:160, 20:240]
    assert np.abs(second - thumb).mean() < 1.0  # the second cell is seed 4's preview (below its label)
    assert_refused(subprocess.run([sys.executable, "-m", "generator.scene", "--seed", "3", "--previews", "--out",
                                   str(tmp_path / "z")], capture_output=True, text=True, cwd=ROOT), "--previews", "--survey")
