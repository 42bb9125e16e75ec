"""Guards of the batch run and of ``verify`` (real processes on real files): Ctrl-C while a
seed waits for its work lock, damaged manifests, entries a manifest cannot list, a seed
folder holding another seed, reordered --outputs, --cpus-per-seed below Ray's precision and
a symlink named as verify's DIR. Only the shared tiny seed 4 is rendered (conftest.finished)."""

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import ROOT, TINY
from conftest import run_generator as run
from exporters.manifest import ManifestError, load_manifest, verify_manifest, write_manifest

SEED4 = ["--seeds", "4", "--colmap-text"]  # the parameters of the shared finished seed

HOLD_LOCK = """
import fcntl, os, sys, time
fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o644)
fcntl.flock(fd, fcntl.LOCK_EX)
print("held", flush=True)
time.sleep(120)
"""


def _env():
    return {k: v for k, v in os.environ.items() if k != "OCIO"}


def _verify(path, *extra):
    return subprocess.run([sys.executable, "-m", "generator", "verify", str(path), *extra], capture_output=True,
                          text=True, cwd=ROOT, env=_env())


def _seed_lines(stdout: str, seed: int) -> list[str]:
    return [l for l in stdout.replace("\r", "\n").splitlines() if l.startswith(f"seed {seed}:")]


def _no_traceback(r):
    assert "Traceback" not in r.stdout + r.stderr, r.stderr[-2000:]


def _copy_seed(finished, dst: Path) -> Path:
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copytree(finished[0] / "seed_000004", dst, copy_function=shutil.copy2)  # keeps mtimes
    return dst


@pytest.mark.pipeline
def test_ctrl_c_while_waiting_for_the_work_lock_is_prompt_and_keeps_a_users_partial_folder(tmp_path):
    """A seed waiting for its work lock (held here by another process) is cancelled at once by
    Ctrl-C, and a `.seed_N.partial` without our marker (the user's) is left alone; the run
    used to wait up to 120 s and then delete it."""
    from generator.batch import folders

    mine = folders.partial_folder(tmp_path, 7) / "mine.txt"
    mine.parent.mkdir()
    mine.write_text("precious")
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK, str(folders.work_lock_file(tmp_path, 7))],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        gen = subprocess.Popen([sys.executable, "-m", "generator", "--out", str(tmp_path), *TINY, "--seeds", "7"],
                               cwd=ROOT, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.time() + 60
        while not folders.lock_file(tmp_path, 7).exists():  # the run has claimed the seed
            assert time.time() < deadline and gen.poll() is None, "the run never claimed the seed"
            time.sleep(0.02)
        time.sleep(1.0)  # now waiting for the work lock
        t0 = time.monotonic()
        gen.send_signal(signal.SIGINT)
        try:
            _, err = gen.communicate(timeout=30)
        except subprocess.TimeoutExpired:
            gen.kill()
            gen.communicate()
            pytest.fail("Ctrl-C did not end the wait for the work lock")
        assert time.monotonic() - t0 < 10
        assert gen.returncode == 130 and "Traceback" not in err, err[-2000:]
        assert err.strip().splitlines()[-1].startswith("interrupted: ")
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.5)
    assert mine.read_text() == "precious"
    assert not folders.lock_file(tmp_path, 7).exists()


@pytest.mark.parametrize("text, error", [("[" * 200_000, "RecursionError"),
                                         ('{"seed": ' + "9" * 5000 + "}", "ValueError")])
def test_an_unparsable_manifest_is_one_line_in_verify_and_in_a_rerun(tmp_path, text, error):
    folder = tmp_path / "seed_000001"
    folder.mkdir()
    (folder / "manifest.json").write_text(text)
    with pytest.raises(ManifestError, match=f"unreadable \\({error}\\)"):
        load_manifest(folder)
    v = _verify(tmp_path)
    _no_traceback(v)
    assert v.returncode == 1 and v.stdout.splitlines() == [f"{folder / 'manifest.json'}: unreadable ({error})"]
    r = run(tmp_path, "--seeds", "1")
    _no_traceback(r)
    assert r.returncode == 3, r.stderr[-2000:]
    [line] = _seed_lines(r.stdout, 1)
    assert f"unreadable ({error}); left alone" in line
    assert (folder / "manifest.json").read_text() == text


def _nested_manifest(folder: Path) -> str:
    (folder / "orbit" / "manifest.json").write_text("junk")
    return "orbit/manifest.json: not listed in the manifest"


def _symlink(folder: Path) -> str:
    (folder / "extra_link").symlink_to("/etc/passwd")
    return "extra_link: a symlink, not listed in the manifest"


def _empty_folder(folder: Path) -> str:
    (folder / "extra_dir").mkdir()
    return "extra_dir: an empty folder, not listed in the manifest"


def _fifo(folder: Path) -> str:
    os.mkfifo(folder / "fifo")
    return "fifo: not a regular file, not listed in the manifest"


@pytest.mark.parametrize("add", [_nested_manifest, _symlink, _empty_folder, _fifo])
def test_every_entry_the_manifest_does_not_list_is_reported(tmp_path, finished, add):
    """Only the seed folder's own manifest.json is not listed: a manifest.json deeper down, a
    symlink, an empty folder or a FIFO is reported by verify and by a rerun."""
    folder = _copy_seed(finished, tmp_path / "seed_000004")
    assert verify_manifest(folder) == []  # the generator's own output: nothing unlisted
    says = add(folder)
    v = _verify(tmp_path)
    _no_traceback(v)
    assert v.returncode == 1 and v.stdout.splitlines() == [f"{folder}/{says}"]
    r = run(tmp_path, *SEED4)
    _no_traceback(r)
    assert r.returncode == 3
    [line] = _seed_lines(r.stdout, 4)
    assert f"complete but {says}; left alone" in line


def test_verify_reports_a_seed_folder_holding_another_seed(tmp_path, finished):
    wrong = _copy_seed(finished, tmp_path / "out" / "seed_000005")
    says = f"{wrong}: its manifest.json is for seed 4, whose folder is named seed_000004"
    for named in (tmp_path / "out", wrong):
        v = _verify(named)
        assert v.returncode == 1 and v.stdout.splitlines() == [says], v.stdout
    assert _verify(_copy_seed(finished, tmp_path / "a_copy")).returncode == 0  # not a seed folder's name


def _fake_seed(out: Path, seed: int, config: dict) -> None:
    from exporters import FORMAT_VERSION

    folder = out / f"seed_{seed:06d}"
    folder.mkdir(parents=True)
    (folder / "labels.json").write_text("[]")
    write_manifest(folder, {"format_version": FORMAT_VERSION, "seed": seed, "config": config, "summary": {}})


@pytest.mark.pipeline
def test_reordered_outputs_are_the_same_parameters(tmp_path):
    """--outputs depth,rgb and rgb,depth write the same seed (modalities go in table order):
    the config stores them in table order, and a manifest of an older run that stored them
    as given still matches; another set is a conflict."""
    from generator.__main__ import parse_args

    def config(outputs):
        return parse_args(["--out", str(tmp_path), *TINY, "--outputs", outputs]).config.to_dict()

    assert config("depth,rgb") == config("rgb,depth") and config("depth,rgb")["outputs"] == ["rgb", "depth"]
    _fake_seed(tmp_path, 1, config("rgb,depth"))
    _fake_seed(tmp_path, 2, config("rgb,depth") | {"outputs": ["depth", "rgb"]})  # as an older run stored it
    for outputs in ("depth,rgb", "rgb,depth"):
        r = run(tmp_path, "--seeds", "1", "2", "--outputs", outputs)
        assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
        assert all("already complete" in _seed_lines(r.stdout, s)[0] for s in (1, 2))
    r = run(tmp_path, "--seeds", "2", "--outputs", "rgb")
    assert r.returncode == 3 and "complete with other parameters: outputs ['rgb', 'depth'] (now ['rgb'])" in r.stdout


def test_cpus_per_seed_below_rays_precision_is_refused_at_parse_time(tmp_path):
    from generator.__main__ import parse_args

    r = run(tmp_path / "out", "--executor", "ray", "--cpus-per-seed", "0.00001")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    [line] = r.stderr.strip().splitlines()
    assert line.startswith("error: argument --cpus-per-seed: expected a positive number of CPUs, at least 0.0001")
    assert not (tmp_path / "out").exists()
    args = parse_args(["--out", str(tmp_path), "--executor", "ray", "--cpus-per-seed", "0.0001"])
    assert args.cpus_per_seed == 0.0001


def test_verify_follows_a_symlink_named_as_dir_but_reports_one_inside_an_output_folder(tmp_path, finished):
    folder = _copy_seed(finished, tmp_path / "data" / "seed_000004")
    link = tmp_path / "link"
    link.symlink_to(folder, target_is_directory=True)
    for named in (str(link), f"{link}/"):
        v = _verify(named)
        assert v.returncode == 0 and v.stdout == "", v.stdout + v.stderr
    entry = tmp_path / "data" / "seed_000005"
    entry.symlink_to(folder, target_is_directory=True)
    v = _verify(tmp_path / "data")
    assert v.returncode == 1 and v.stdout.splitlines() == [f"{entry}: a symlink, not a seed folder"]
