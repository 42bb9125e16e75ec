"""Issue #36, items 4, 5 and 9: every file a reader trusts is checked (PNG chunks against
their CRCs, JSON against the seed's manifest, the manifest against its own checksum, PLY
element counts against the file's length), and what a file declares is checked before the
work it implies (array shapes, vertex counts, text size). Real seeds, real processes."""

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, assert_refused, run_evaluation
from datasets import DatasetError, FrameDataset, Scene
from evaluation.inputs import MAX_CLOUD_POINTS, InputError, read_cloud
from exporters.manifest import ManifestError, load_manifest
from exporters.nerfstudio import read_depth_png
from exporters.ply import PlyError, read_ply, write_ply
from trajectories import Trajectory
from trajectories.arrays import EXPANSION_FLOOR, ArrayFileError, declared_arrays, load_arrays


def flip_bit(path, offset, bit=0):
    data = bytearray(path.read_bytes())
    data[offset] ^= 1 << bit
    path.write_bytes(bytes(data))


def idat_offset(path) -> int:
    """A byte inside the image data of a PNG (past its first IDAT chunk's header)."""
    data = path.read_bytes()
    start = data.index(b"IDAT") + 4
    length = int.from_bytes(data[start - 8:start - 4], "big")
    return start + length // 2


@pytest.fixture
def seed_copy(seed_folder, tmp_path):
    copy = tmp_path / "seed_000004"
    shutil.copytree(seed_folder, copy)
    return copy


def silent_flip(png) -> int:
    """The offset of the first bit flip in ``png``'s image data that Pillow alone decodes
    without an error as other pixels (the issue's case 4: it does not check the image data's CRC)."""
    from PIL import Image

    pristine = png.read_bytes()
    with Image.open(png) as im:
        good = np.asarray(im).copy()
    start = pristine.index(b"IDAT") + 4
    for offset in range(start + 2, start + int.from_bytes(pristine[start - 8:start - 4], "big")):
        flip_bit(png, offset, 2)
        try:
            with Image.open(png) as im:
                other = np.asarray(im)
        except (OSError, ValueError):
            other = good
        png.write_bytes(pristine)
        if other.shape == good.shape and not np.array_equal(other, good):
            return offset
    raise AssertionError(f"{png}: no bit flip decodes as other pixels")


@pytest.mark.parametrize("name, key", [("rgb_000001.png", "rgb"), ("label_000001.png", "label"),
                                       ("instance_000001.png", "instance")])
def test_a_flipped_bit_in_a_png_is_refused_not_decoded(seed_copy, name, key):
    """The issue's case 4: Pillow decodes a PNG whose image data fails its CRC as other pixels."""
    png = seed_copy / "orbit" / name
    good = Scene(seed_copy)["orbit"].read(1, [key])[key]
    for offset in (silent_flip(png), idat_offset(png), len(png.read_bytes()) - 20):  # other pixels; data; a CRC
        pristine = png.read_bytes()
        flip_bit(png, offset, 2)
        with pytest.raises(DatasetError, match=rf"{name}: damaged PNG .*fails its CRC"):
            Scene(seed_copy)["orbit"].read(1, [key])
        with pytest.raises(DatasetError, match=name):
            FrameDataset([seed_copy], keys=(key,))[1]
        png.write_bytes(pristine)
    png.write_bytes(png.read_bytes() + b"trailing bytes")
    with pytest.raises(DatasetError, match="after its IEND chunk"):
        Scene(seed_copy)["orbit"].read(1, [key])
    png.write_bytes(pristine)
    np.testing.assert_array_equal(Scene(seed_copy)["orbit"].read(1, [key])[key], good)


def change_one_digit(path) -> None:
    """Change one digit of a JSON file (one letter where it has no digit): still valid JSON,
    another value (what a flipped bit often does)."""
    data = bytearray(path.read_bytes())
    kind = str.isdigit if any(chr(b).isdigit() for b in data) else str.islower
    i = max(k for k in range(len(data) // 2 + 1) if kind(chr(data[k])))
    data[i] = ord("7" if kind is str.isdigit else "q") if data[i] not in b"7q" else ord("3")
    path.write_bytes(bytes(data))
    json.loads(data)


@pytest.mark.parametrize("name", ["orbit/coco.json", "orbit/boxes3d.json", "orbit/frames.json", "labels.json"])
def test_json_files_are_checked_against_the_manifest(seed_copy, name):
    change_one_digit(seed_copy / name)
    with pytest.raises(DatasetError, match=rf"{name}: damaged file \(its sha256 differs from the seed's manifest\)"):
        scene = Scene(seed_copy)
        scene["orbit"].annotations(0)
        scene["orbit"][0]


def test_a_label_table_damaged_in_place_is_refused_by_the_evaluation(seed_copy):
    """The evaluation reads labels.json beside a ground-truth file through the same check."""
    from evaluation.inputs import read_label_table

    labels = seed_copy / "labels.json"
    names = read_label_table(labels)
    labels.write_text(json.dumps(names[::-1]))  # valid, the same names, other ids
    with pytest.raises(InputError, match="labels.json: damaged file .*sha256"):
        read_label_table(labels)


def test_the_nerfstudio_depth_unit_and_png_are_checked(seed_copy):
    depth = seed_copy / "orbit" / "depth_000000.png"
    assert np.isfinite(read_depth_png(depth)).any()
    change_one_digit(seed_copy / "orbit" / "transforms.json")
    with pytest.raises(ValueError, match="transforms.json"):
        read_depth_png(depth)
    flip_bit(depth, idat_offset(depth))
    with pytest.raises(ValueError, match="fails its CRC"):
        read_depth_png(depth, unit=0.001)


def test_the_manifest_carries_a_checksum_of_its_own(seed_copy):
    manifest = load_manifest(seed_copy)
    assert len(manifest["checksum"]) == 64
    change_one_digit(seed_copy / "manifest.json")
    with pytest.raises(ManifestError, match="differ from its own checksum"):
        load_manifest(seed_copy)
    with pytest.raises(DatasetError, match="manifest.json"):
        Scene(seed_copy)


def test_a_file_added_to_a_seed_is_not_read_as_its_own(seed_copy):
    (seed_copy / "orbit" / "coco.json").rename(seed_copy / "orbit" / "coco.json.bak")
    shutil.copy(seed_copy / "orbit" / "coco.json.bak", seed_copy / "spline" / "unlisted.json")
    from exporters.jsonfile import read_json_file
    from exporters.hdf5 import DamagedFileError

    with pytest.raises(DamagedFileError, match="not listed in the manifest"):
        read_json_file(seed_copy / "spline" / "unlisted.json", "COCO file")


# ---- item 5: PLY element counts against the file ----------------------------------------------

def xyz(n):
    return {c: np.arange(n, dtype=np.float32) for c in "xyz"}


@pytest.mark.parametrize("variant", ["ascii 1 of 3", "binary 1 of 1000", "mesh + bytes", "ascii mesh + rows"])
def test_a_ply_header_that_undercounts_its_rows_is_refused(tmp_path, seed_folder, variant):
    path = tmp_path / "p.ply"
    if variant == "ascii 1 of 3":
        path.write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                        "property float z\nend_header\n0 0 0\n1 1 1\n2 2 2\n")
    elif variant == "binary 1 of 1000":
        write_ply(path, xyz(1000))
        path.write_bytes(path.read_bytes().replace(b"element vertex 1000", b"element vertex 1"))
    elif variant == "mesh + bytes":
        write_ply(path, xyz(3), faces=np.array([[0, 1, 2]]))
        path.write_bytes(path.read_bytes() + bytes(13))
    else:
        path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                        "0 0 0\n1 1 1\n2 2 2\n3 0 1 2\n3 0 2 1\n")
    with pytest.raises(PlyError, match="after the last element|more data than its header declares"):
        read_ply(path)
    assert_refused(run_evaluation("reconstruction", "--gt", seed_folder, "--pred", path), path.name)


def test_a_ply_declaring_too_many_vertices_is_refused_before_reading(tmp_path):
    path = tmp_path / "huge.ply"
    path.write_text(f"ply\nformat binary_little_endian 1.0\nelement vertex {MAX_CLOUD_POINTS + 1}\n"
                    "property float x\nproperty float y\nproperty float z\nend_header\n")
    with pytest.raises(InputError, match="over the limit"):
        read_cloud(path)
    write_ply(path, xyz(5))
    assert len(read_ply(path).points) == 5  # a file whose counts fit still reads


# ---- item 9: declared shapes before the work they imply ---------------------------------------

MEASURE = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[2:]); "
           "open(sys.argv[1], 'w').write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)); "
           "sys.exit(r.returncode)")


def peak_rss_mb(args, tmp_path) -> tuple[subprocess.CompletedProcess, float]:
    """A real ``python -m evaluation`` process and its peak resident memory in MB (measured by
    a fresh parent process, whose only child it is)."""
    report = tmp_path / "maxrss.txt"
    r = subprocess.run([sys.executable, "-c", MEASURE, str(report), sys.executable, "-m", "evaluation",
                        *map(str, args)], capture_output=True, text=True, cwd=ROOT, timeout=300)
    return r, int(report.read_text()) / 1024  # ru_maxrss is in KB


def test_a_small_npz_never_costs_gigabytes(seed_folder, timeline_seed_folder, tmp_path):
    """The issue's case 9: a file of a few MB whose members declare large shapes is refused
    from its headers (the largest child process stays far below the declared size)."""
    cloud = tmp_path / "cloud.npz"
    np.savez_compressed(cloud, points=np.zeros((40_000_000, 3), np.float32))  # 480 MB in under 1 MB
    masks = tmp_path / "masks.npz"
    np.savez_compressed(masks, masks=np.zeros((3000, 480, 640), bool))  # 922 MB in about 1 MB
    tracks = tmp_path / "tracks.npz"
    np.savez_compressed(tracks, tracks=np.zeros((20_000_000, 3, 2)), occluded=np.zeros((20_000_000, 3), bool))
    assert max(p.stat().st_size for p in (cloud, masks, tracks)) < 2 << 20
    runs = [(["reconstruction", "--gt", seed_folder, "--pred", cloud], "the limit is"),
            (["change", "--gt", timeline_seed_folder, "--stages", 0, 1, "--pred", masks], "the ground truth's"),
            (["tracks", "--gt", seed_folder / "orbit", "--pred", tracks], "expected")]
    for args, words in runs:
        r, peak = peak_rss_mb(args, tmp_path)
        assert_refused(r, words)
        assert peak < 500, (args[0], peak)


def test_declared_sizes_must_fit_the_file(tmp_path):
    ok = tmp_path / "ok.npy"
    np.save(ok, np.arange(12.0).reshape(4, 3))
    assert declared_arrays(ok).shape == (4, 3)
    short = tmp_path / "short.npy"
    short.write_bytes(ok.read_bytes()[:-8])
    longer = tmp_path / "long.npy"
    longer.write_bytes(ok.read_bytes() + bytes(8))
    header_only = tmp_path / "header.npy"  # declares 1e12 rows and holds none
    header_only.write_bytes(ok.read_bytes().replace(b"(4, 3)", b"(1000000000000, 3)")[:128])
    for path in (short, longer, header_only):
        with pytest.raises(ArrayFileError, match="declares .* but the file holds"):
            load_arrays(path)
    bomb = tmp_path / "bomb.npz"
    np.savez_compressed(bomb, a=np.zeros(EXPANSION_FLOOR // 8 + 1024))
    with pytest.raises(ArrayFileError, match="over 32x"):
        load_arrays(bomb)
    np.savez_compressed(bomb, a=np.zeros(1000))  # small: under the floor, read
    assert load_arrays(bomb)["a"].shape == (1000,)


def test_trajectories_label_files_and_text_clouds_have_limits(seed_folder, tmp_path):
    walk = tmp_path / "walk.npz"
    header = json.dumps({"format": "buildee-trajectory-1", "kind": "random_walk"})
    np.savez_compressed(walk, poses=np.zeros((2_000_000, 4, 4)), timestamps=np.zeros(2_000_000),
                        actions=np.array(["forward"] * 1_999_999), header=np.array(header))
    with pytest.raises(ValueError, match="at most 1,000,000 poses"):
        Trajectory.load(walk)
    labels = tmp_path / "labels.npy"
    np.save(labels, np.zeros(10, np.int64))
    labels.write_bytes(labels.read_bytes().replace(b"(10,)", b"(40000000,)"))
    pred = tmp_path / "p.npy"
    np.save(pred, np.zeros((10, 3)))
    assert_refused(run_evaluation("reconstruction", "--gt", seed_folder, "--pred", pred, "--pred-labels", labels),
                   "labels.npy")
    text = tmp_path / "cloud.txt"
    with open(text, "wb") as f:
        f.truncate((1 << 30) + 1)  # a sparse file: no disk used
    with pytest.raises(InputError, match="give large clouds as NPY or binary PLY"):
        read_cloud(text)


# ---- lesser items of the issue ----------------------------------------------------------------

def test_change_predictions_say_what_is_wrong(timeline_seed_folder, tmp_path):
    from exporters.changes import read_changes

    shape = read_changes(timeline_seed_folder).pair(0, 1).masks["orbit"].shape  # masks the old code scored
    both = tmp_path / "both.npz"
    np.savez(both, masks=np.zeros(shape, bool), xyz=np.zeros((1, 3)), change=np.ones(1))
    change = ["change", "--gt", timeline_seed_folder, "--stages", 0, 1, "--pred"]
    assert_refused(run_evaluation(*change, both), "holds both masks and a change cloud")
    assert_refused(run_evaluation(*change, timeline_seed_folder / "changes.h5"), "changes.h5", "an HDF5 file")


def test_change_pairs_are_listed_once(timeline_seed_folder):
    from datasets.change import ChangePairDataset

    with pytest.raises(DatasetError, match="pairs lists pair 1 twice"):
        ChangePairDataset(timeline_seed_folder, pairs=[1, 1])
    with pytest.raises(DatasetError, match="must be a list of integers"):
        ChangePairDataset(timeline_seed_folder, pairs=1)
    assert len(ChangePairDataset(timeline_seed_folder, pairs=[2, 1])) == len(ChangePairDataset(timeline_seed_folder))
