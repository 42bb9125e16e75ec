"""The on-disk formats of LiDAR sweeps (exporters/semantickitti.py, exporters/las.py), checked
with the readers their users have: numpy as SemanticKITTI's tools read .bin and .label files,
pykitti, PyYAML and laspy; plus our own readers' bit-exact round trip, same bytes for the same
scans, and one-line refusals of damaged folders and of ids that do not fit."""

import json
import math

import laspy
import numpy as np
import pykitti
import pytest
import yaml

from exporters import VERSION_REMEDY
from exporters.hdf5 import DamagedFileError
from exporters.las import read_las, write_las
from exporters.semantickitti import ScanWriter, read_lidar_json, read_scan, read_scans, scan_folder, write_scans
from generator.lidar.returns import Scan
from generator.scene.taxonomy import CLASS_COLORS, CLASSES

N = 300
# the taxonomy plus made-up classes, so that class ids above 255 occur
TABLE = list(CLASSES) + [f"Extra{i}" for i in range(400 - len(CLASSES))]
COLOURS = [CLASS_COLORS[c] for c in CLASSES] + [(i % 256, (7 * i) % 256, (13 * i) % 256) for i in range(len(CLASSES), 400)]
SUMMARY = {"name": "test-16", "beams": 16, "range_m": [0.5, 100.0], "rate_hz": 10.0}
FIELDS = ("xyz", "xyz_deskewed", "intensity", "ring", "time", "label", "instance")


def pose(angle: float, axis, t) -> np.ndarray:
    """A rigid 4x4: rotation of ``angle`` radians about ``axis`` (Rodrigues), then ``t``."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    m = np.eye(4)
    m[:3, :3] = np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K
    m[:3, 3] = t
    return m


def make_scan(index: int, with_change: bool) -> Scan:
    rng = np.random.default_rng(100 + index)
    xyz = rng.uniform(-40, 40, (N, 3)).astype(np.float32)
    label = rng.integers(0, len(TABLE), N).astype(np.uint16)
    label[:3] = [0, 255, 399]
    instance = rng.integers(0, 65536, N).astype(np.uint16)
    instance[:2] = [0, 65535]
    return Scan(sensor="test-16", index=index, start_time_s=0.1 * index + 1 / 3,
                world_from_sensor=pose(0.4 + 0.3 * index, [0.2, -0.3, 1.0], [123.4 + index, -56.7, 8.9]),
                xyz=xyz, xyz_deskewed=(xyz + rng.normal(0, 0.01, (N, 3))).astype(np.float32),
                intensity=rng.random(N).astype(np.float32), ring=rng.integers(0, 16, N).astype(np.uint16),
                time=np.sort(rng.uniform(0, 0.1, N)).astype(np.float32), label=label, instance=instance,
                change=rng.integers(0, 5, N).astype(np.int8) if with_change else None)


SCANS = [make_scan(0, False), make_scan(1, True), make_scan(2, False)]


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    out = scan_folder(tmp_path_factory.mktemp("traj"), "test-16")
    write_scans(out, SCANS, SUMMARY, TABLE, COLOURS)
    return out


def copy_of(tmp_path):
    """The same scans written again, into a folder of ``tmp_path``."""
    dst = tmp_path / "copy"
    write_scans(dst, SCANS, SUMMARY, TABLE, COLOURS)
    return dst


def one_line(exc: pytest.ExceptionInfo) -> str:
    text = str(exc.value)
    assert "\n" not in text and text
    return text


def test_bin_and_label_files_read_as_semantickitti_tools_read_them(folder):
    for s in SCANS:
        name = f"{s.index:06d}"
        velo = np.fromfile(folder / "velodyne" / f"{name}.bin", dtype=np.float32).reshape(-1, 4)
        assert np.array_equal(velo, np.column_stack([s.xyz, s.intensity]))
        assert np.array_equal(pykitti.utils.load_velo_scan(str(folder / "velodyne" / f"{name}.bin")), velo)
        deskewed = np.fromfile(folder / "velodyne_deskewed" / f"{name}.bin", dtype=np.float32).reshape(-1, 4)
        assert np.array_equal(deskewed, np.column_stack([s.xyz_deskewed, s.intensity]))
        label = np.fromfile(folder / "labels" / f"{name}.label", dtype=np.uint32)
        assert np.array_equal(label & 0xFFFF, s.label) and np.array_equal(label >> 16, s.instance)
        assert np.array_equal(np.fromfile(folder / "times" / f"{name}.bin", dtype=np.float32), s.time)
        assert np.array_equal(np.fromfile(folder / "rings" / f"{name}.bin", dtype=np.uint16), s.ring)
        change = folder / "changes" / f"{name}.bin"
        assert change.is_file() == (s.change is not None)
        if s.change is not None:
            assert np.array_equal(np.fromfile(change, dtype=np.int8), s.change)


def test_pykitti_odometry_loads_the_folder_as_a_sequence(folder, tmp_path):
    # pykitti wants base/sequences/<seq>/ and base/poses/<seq>.txt: links to our one folder
    (tmp_path / "sequences").mkdir()
    (tmp_path / "poses").mkdir()
    (tmp_path / "sequences" / "00").symlink_to(folder)
    (tmp_path / "poses" / "00.txt").symlink_to(folder / "poses.txt")
    odo = pykitti.odometry(str(tmp_path), "00")
    assert len(odo) == len(SCANS) == len(odo.velo_files) == len(odo.poses)
    assert np.array_equal(odo.calib.T_cam0_velo, np.eye(4))
    assert [t.total_seconds() for t in odo.timestamps] == pytest.approx([s.start_time_s for s in SCANS], abs=1e-6)
    for s, velo in zip(SCANS, odo.velo):
        assert np.array_equal(velo, np.column_stack([s.xyz, s.intensity]))
    assert np.array_equal(odo.poses[0], np.eye(4))


def test_poses_are_relative_to_the_first_scan_and_lidar_json_holds_the_absolute_ones(folder):
    rel = np.loadtxt(folder / "poses.txt").reshape(-1, 3, 4)
    doc = json.loads((folder / "lidar.json").read_text())
    assert len(rel) == len(doc["scans"]) == len(SCANS)
    assert np.array_equal(rel[0], np.eye(3, 4))
    world0 = np.array(doc["scans"][0]["world_from_sensor"])
    for s, r, row in zip(SCANS, rel, doc["scans"]):
        world = np.array(row["world_from_sensor"])
        assert np.array_equal(world, s.world_from_sensor)  # exact floats
        assert np.allclose(world0 @ np.vstack([r, [0, 0, 0, 1]]), world, atol=1e-12, rtol=0)
        assert (row["index"], row["start_time_s"], row["returns"]) == (s.index, s.start_time_s, len(s))
    assert [float(t) for t in (folder / "times.txt").read_text().split()] == [s.start_time_s for s in SCANS]
    calib = pykitti.utils.read_calib_file(str(folder / "calib.txt"))
    assert sorted(calib) == ["P0", "P1", "P2", "P3", "Tr"]
    assert all(np.array_equal(v, np.eye(3, 4).ravel()) for v in calib.values())
    assert doc["sensor_summary"] == SUMMARY and doc["sensor"] == "test-16" and doc["classes"] == TABLE


def test_labels_yaml_maps_ids_to_the_taxonomy_in_bgr(folder):
    table = yaml.safe_load((folder / "labels.yaml").read_text())
    assert table["labels"] == dict(enumerate(TABLE))
    assert table["color_map"] == {i: [b, g, r] for i, (r, g, b) in enumerate(COLOURS)}
    assert table["learning_map"] == table["learning_map_inv"] == {i: i for i in range(len(TABLE))}
    assert "content" not in table


def test_read_scans_round_trips_every_field_bit_exactly(folder):
    back = read_scans(folder)
    assert len(back) == len(SCANS)
    for s, b in zip(SCANS, back):
        assert (b.sensor, b.index, b.start_time_s) == (s.sensor, s.index, s.start_time_s)
        assert np.array_equal(b.world_from_sensor, s.world_from_sensor) and b.world_from_sensor.dtype == np.float64
        for name in FIELDS:
            got, want = getattr(b, name), getattr(s, name)
            assert got.dtype == want.dtype and got.tobytes() == want.tobytes(), name
        assert (b.change is None) == (s.change is None)
        if s.change is not None:
            assert b.change.dtype == np.int8 and np.array_equal(b.change, s.change)
    assert read_scan(folder, 1).index == 1 and read_lidar_json(folder)["scans"][2]["returns"] == N


def test_las_holds_world_points_to_a_tenth_of_a_millimetre_and_every_id_exactly(tmp_path):
    s = SCANS[1]
    path = write_las(tmp_path / "scan.las", s, TABLE, gps_time_offset_s=1000.25)
    las = laspy.read(path)
    assert (las.header.version.major, las.header.version.minor, las.header.point_format.id) == (1, 4, 6)
    assert las.header.generating_software == las.header.system_identifier == "buildee-sites"
    world = np.column_stack([las.x, las.y, las.z])
    assert np.abs(world - s.world_points()).max() <= 5e-5 + 1e-9
    assert np.array_equal(las.header.offsets, np.round(s.world_from_sensor[:3, 3]))
    assert np.array_equal(las.classification, np.minimum(s.label, 255))
    for name in ("label", "instance", "ring"):
        assert np.array_equal(las[name], getattr(s, name)), name
    assert np.array_equal(las.change, s.change)
    assert np.array_equal(las.gps_time, (s.start_time_s + s.time.astype(np.float64)) + 1000.25)
    assert np.array_equal(las.intensity, np.round(s.intensity.astype(np.float64) * 65535).astype(np.uint16))
    assert (np.asarray(las.point_source_id) == s.index).all()
    back = read_las(path)
    assert back["metadata"]["classes"] == TABLE and np.array_equal(back["metadata"]["world_from_sensor"], s.world_from_sensor)
    assert np.array_equal(back["label"], s.label) and np.array_equal(back["xyz"], world)
    assert np.abs(back["intensity"] - s.intensity).max() <= 0.5 / 65535 + 1e-7
    assert read_las(write_las(tmp_path / "no_change.las", SCANS[0], TABLE))["change"] is None


def test_same_scans_give_the_same_bytes(folder, tmp_path):
    other = copy_of(tmp_path)
    files = sorted(p.relative_to(folder) for p in folder.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(other) for p in other.rglob("*") if p.is_file())
    assert all((folder / f).read_bytes() == (other / f).read_bytes() for f in files)
    a, b = write_las(tmp_path / "a.las", SCANS[1], TABLE), write_las(tmp_path / "b.las", SCANS[1], TABLE)
    assert a.read_bytes() == b.read_bytes()


def test_writer_streams_and_lists_its_files(tmp_path):
    writer = ScanWriter(tmp_path / "s", SUMMARY, TABLE, COLOURS)
    for s in SCANS:
        writer.add(s)
    files = writer.close()
    assert all(p.is_absolute() and p.is_file() for p in files) and files[-1].name == "lidar.json"
    assert len(files) == 5 * len(SCANS) + 1 + 5  # per scan 5 files, one changes file, 5 per folder


@pytest.mark.parametrize("damage, words", [
    (lambda f: (f / "velodyne" / "000001.bin").write_bytes((f / "velodyne" / "000001.bin").read_bytes()[:-3]),
     "truncated"),
    (lambda f: (f / "labels" / "000001.label").write_bytes((f / "labels" / "000001.label").read_bytes()[:-4]),
     "holds 299 returns"),
    (lambda f: (f / "rings" / "000001.bin").unlink(), "no such file"),
    (lambda f: (f / "lidar.json").write_text((f / "lidar.json").read_text().replace('"format_version": "',
                                                                                     '"format_version": "0.0-')),
     VERSION_REMEDY),
])
def test_damaged_folders_are_one_line_errors(folder, tmp_path, damage, words):
    copy = copy_of(tmp_path)
    damage(copy)
    with pytest.raises(DamagedFileError) as exc:
        read_scans(copy)
    assert words in one_line(exc)


def test_missing_folder_and_damaged_las_are_one_line_errors(tmp_path):
    with pytest.raises(DamagedFileError) as exc:
        read_scan(tmp_path / "nowhere", 0)
    assert "no such folder" in one_line(exc)
    path = write_las(tmp_path / "scan.las", SCANS[0], TABLE)
    path.write_bytes(path.read_bytes()[:200])
    with pytest.raises(DamagedFileError) as exc:
        read_las(path)
    one_line(exc)


def test_ids_that_do_not_fit_and_misordered_scans_are_refused(tmp_path):
    s = SCANS[0]
    instance = s.instance.astype(np.uint32)
    instance[5] = 65536
    wide = Scan(**{**s.__dict__, "instance": instance})
    with pytest.raises(ValueError) as exc:
        write_scans(tmp_path / "a", [wide], SUMMARY, TABLE, COLOURS)
    assert "instance 65536" in one_line(exc) and "16 bits" in str(exc.value)
    with pytest.raises(ValueError) as exc:
        write_scans(tmp_path / "b", [s], SUMMARY, TABLE[:30], COLOURS[:30])
    assert "label" in one_line(exc) and "30 classes" in str(exc.value)
    with pytest.raises(ValueError) as exc:
        write_las(tmp_path / "c.las", s, TABLE[:30])
    one_line(exc)
    with pytest.raises(ValueError) as exc:
        write_scans(tmp_path / "d", [SCANS[1]], SUMMARY, TABLE, COLOURS)
    assert "expected 0" in one_line(exc)
    write_scans(tmp_path / "e", SCANS[:1], SUMMARY, TABLE, COLOURS)
    with pytest.raises(ValueError) as exc:
        write_scans(tmp_path / "e", SCANS, SUMMARY, TABLE, COLOURS)
    assert "not an empty folder" in one_line(exc)
