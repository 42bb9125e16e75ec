"""The environment's site cache (generator/envs/scenes.py, site_cache.py; docs/envs.md,
"Scenes"): it never renames or removes a folder it did not make, never writes inside a
generated dataset, checks a cached site against its recorded hashes before every use, and
removes what killed builds left behind. One small site is built once and copied into each
test's folder."""

import fcntl
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.seeding import np_random

from exporters import FORMAT_VERSION
from exporters.manifest import PARTIAL_MARKER, write_manifest
from generator.envs import EXPLORATION_ID
from generator.envs.exploration import check_keywords
from generator.envs.scenes import site_scene

ROOT = Path(__file__).resolve().parents[1]
ENTRY = "small_seed3"
ENV_KW = dict(seeds=[3], scene_preset="small", resolution=(16, 16), points_density=0.3, max_steps=3)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """The entry of the small site of seed 3, built once by the real cache."""
    cache = tmp_path_factory.mktemp("cache")
    site_scene(3, "small", cache)
    return cache / ENTRY


@pytest.fixture
def cache(built, tmp_path):
    """This test's own cache folder, holding a copy of the built entry."""
    shutil.copytree(built, tmp_path / "cache" / ENTRY)
    return tmp_path / "cache"


def tree(folder: Path) -> dict:
    """Every path under ``folder`` (hidden ones too, links not followed) -> its bytes, its
    link target or 'folder'; lock files left out."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs + files:
            p = Path(root) / name
            rel = p.relative_to(folder).as_posix()
            if p.is_symlink():
                out[rel] = f"-> {os.readlink(p)}"
            elif p.is_dir():
                out[rel] = "folder"
            elif not name.endswith(".lock"):
                out[rel] = p.read_bytes()
    return out


def flip(path: Path, offset: int, bit: int = 0) -> None:
    data = bytearray(path.read_bytes())
    data[offset] ^= 1 << bit
    path.write_bytes(bytes(data))


def assert_one_line_refusal(err, folder: Path) -> None:
    text = str(err.value)
    assert "\n" not in text and str(folder) in text, text
    assert text.endswith("it is left untouched: move it away, or pass another cache_dir"), text


# ---- item 2: a folder the cache did not make -----------------------------------------------------
def foreign_folders(built: Path, base: Path) -> dict:
    """name -> (a cache folder whose entry small_seed3 the cache did not make, or holds
    something it did not write; the words of the reason given)."""
    def user_folder(name, with_scene_json=None):
        entry = base / name / ENTRY
        entry.mkdir(parents=True)
        (entry / "thesis.tex").write_text("my thesis, chapter 3\n")
        if with_scene_json is not None:
            (entry / "scene.json").write_text(json.dumps(with_scene_json))
        return entry.parent

    meta = json.loads((built / "scene.json").read_text())
    no_marker = "no .buildee-site-cache marker in it"
    cases = {"user folder": (user_folder("a"), no_marker),
             "user folder with the site's own scene.json": (user_folder("b", meta), no_marker),
             "user folder with a stale scene.json": (user_folder("c", meta | {"code_key": "0" * 64}), no_marker)}
    for name, folder, extra, words in (("entry plus a user's file", "e", "notes.txt", "it holds 'notes.txt'"),
                                       ("entry plus a user's folder", "f", "runs", "it holds 'runs'"),
                                       ("entry from before markers", "g", None, no_marker)):
        entry = base / folder / ENTRY
        shutil.copytree(built, entry)
        if extra == "notes.txt":
            (entry / extra).write_text("do not lose me\n")
        elif extra == "runs":
            (entry / extra).mkdir()
        else:
            (entry / ".buildee-site-cache").unlink(missing_ok=True)
        cases[name] = entry.parent, words
    entry = base / "h" / ENTRY  # an entry whose site.blend is now a link to a user's file
    shutil.copytree(built, entry)
    (entry / "site.blend").unlink()
    (base / "mine.blend").write_bytes((built / "site.blend").read_bytes())
    (entry / "site.blend").symlink_to(base / "mine.blend")
    cases["entry whose site.blend is a link"] = entry.parent, "its 'site.blend' is a link or a folder"
    elsewhere = user_folder("d")
    (base / "link").mkdir()
    (base / "link" / ENTRY).symlink_to(elsewhere / ENTRY)
    cases["a link to a user folder"] = base / "link", "a link or a file, not a folder"
    (base / "file").mkdir()
    (base / "file" / ENTRY).write_text("a file, not a folder\n")
    cases["a file named like the entry"] = base / "file", "a link or a file, not a folder"
    return cases


def test_a_folder_the_cache_did_not_make_is_never_renamed_or_removed(built, tmp_path):
    for name, (cache_dir, words) in foreign_folders(built, tmp_path).items():
        before = tree(tmp_path)
        with pytest.raises(ValueError, match=r"^cache_dir holds .*which the site cache did not make") as err:
            site_scene(3, "small", cache_dir)
        assert_one_line_refusal(err, cache_dir / ENTRY)
        assert words in str(err.value), (name, str(err.value))
        assert tree(tmp_path) == before, name  # nothing renamed, removed or added
        assert not [p for p in cache_dir.iterdir() if p.name.startswith(f".{ENTRY}-")], name


def test_the_issues_case_through_the_environment(tmp_path):
    entry = tmp_path / ENTRY
    entry.mkdir()
    (entry / "results.csv").write_text("episode,return\n0,12.5\n")
    env = gym.make(EXPLORATION_ID, **ENV_KW, cache_dir=tmp_path)
    with pytest.raises(ValueError) as err:
        env.reset(seed=1)
    env.close()
    assert_one_line_refusal(err, entry)
    assert tree(tmp_path) == {ENTRY: "folder", f"{ENTRY}/results.csv": b"episode,return\n0,12.5\n"}


def test_a_cache_dir_inside_a_generated_dataset_is_refused(tmp_path):
    data = tmp_path / "data"
    seed = data / "seed_000003"
    (seed / "phase_1").mkdir(parents=True)
    (seed / "phase_1" / "site.json").write_text("{}")
    write_manifest(seed, {"format_version": FORMAT_VERSION, "seed": 3, "config": {}})
    partial = data / ".seed_000005.partial"
    partial.mkdir()
    (partial / PARTIAL_MARKER).write_text("")
    real_seed, real_partial = Path(os.path.realpath(seed)), Path(os.path.realpath(partial))
    cases = ((seed, real_seed), (seed / "phase_1", real_seed), (seed / "phase_1" / "sites", real_seed),
             (seed / "sites", real_seed), (partial, real_partial), (partial / "sites", real_partial))
    before = tree(data)
    for cache_dir, dataset in cases:
        for attempt in (lambda: check_keywords(seeds=[3], cache_dir=cache_dir),
                        lambda: gym.make(EXPLORATION_ID, **ENV_KW, cache_dir=cache_dir),
                        lambda: site_scene(3, "small", cache_dir)):
            with pytest.raises(ValueError, match=rf"^cache_dir {re.escape(str(cache_dir))}: lies inside the "
                                                 rf"generated seed folder {re.escape(str(dataset))}") as err:
                attempt()
            assert "\n" not in str(err.value)
        assert tree(data) == before, cache_dir  # nothing written into the dataset
    assert check_keywords(seeds=[3], cache_dir=data)["cache_dir"] == data  # beside seed folders: fine


# ---- item 3: a damaged cached site -------------------------------------------------------------
def test_flipped_bytes_in_site_blend_or_scene_json_are_rebuilt_with_a_warning(cache, built):
    entry = cache / ENTRY
    reference = site_scene(3, "small", built.parent)
    first_digit_of_start = re.search(r'"start": \[\s*\[\s*-?\d', (entry / "scene.json").read_text()).end() - 1
    for name, offset in (("site.blend", (entry / "site.blend").stat().st_size // 2),
                         ("scene.json", first_digit_of_start)):
        flip(entry / name, offset)
        with pytest.warns(UserWarning) as caught:
            spec = site_scene(3, "small", cache)
        messages = [str(w.message) for w in caught]
        assert messages == [f"{entry}: the cached site is damaged ({name} differs from its recorded sha256 (or "
                            "cannot be read)); rebuilding it"], messages
        # the same site again (built anew: the .blend's bytes vary, its content does not)
        assert np.array_equal(spec.start, reference.start) and np.array_equal(spec.bounds, reference.bounds)
        assert (entry / "scene.json").read_bytes() == (built / "scene.json").read_bytes()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            site_scene(3, "small", cache)  # intact now: no warning, no rebuild
    assert sorted(p.name for p in cache.iterdir()) == [f".{ENTRY}.lock", ENTRY]


def test_no_single_bit_flip_of_an_entry_is_taken_for_intact(cache):
    """Bits flipped in every file of an entry, the record included: each is damage (rebuilt) or
    no proof of ownership (refused); never 'intact', unless the record reads back the same."""
    from generator.envs.site_cache import MARKER, ForeignEntry, entry_state

    entry = cache / ENTRY
    assert entry_state(entry) == ("intact", "")
    rng = np.random.default_rng(0)
    for name in ("site.blend", "scene.json", "site.json", "map.png", MARKER):
        path = entry / name
        original = path.read_bytes()
        offsets = range(len(original)) if name == MARKER else rng.integers(len(original), size=12)
        for offset in offsets:
            flip(path, int(offset), int(rng.integers(8)))
            try:
                state, problem = entry_state(entry)
            except ForeignEntry:
                state, problem = "foreign", ""
            if name != MARKER:
                assert (state, problem) == ("damaged", f"{name} differs from its recorded sha256 (or cannot be read)")
            elif state == "intact":
                assert json.loads(path.read_bytes()) == json.loads(original), offset  # white space changed
            else:
                assert state in ("damaged", "foreign"), (offset, state)
            path.write_bytes(original)
    assert entry_state(entry) == ("intact", "")
    (entry / "map.png").unlink()  # a file of ours deleted: damage, not a user's doing to keep
    assert entry_state(entry) == ("damaged", "map.png is missing")


def test_the_environment_checks_the_site_before_every_load(cache, tmp_path):
    from test_envs import room_scene

    room = room_scene(tmp_path / "room.blend")
    draws = {s: int(np_random(s)[0].integers(2)) for s in range(20)}
    on_site, on_room = (next(s for s, i in draws.items() if i == k) for k in (0, 1))
    env = gym.make(EXPLORATION_ID, **ENV_KW, blend_files=[room], cache_dir=cache)
    obs, info = env.reset(seed=on_site)
    assert info["scene"] == ENTRY
    env.reset(seed=on_room)
    blend = cache / ENTRY / "site.blend"
    flip(blend, blend.stat().st_size // 3, 5)  # damaged while the environment holds the scene
    with pytest.warns(UserWarning, match=r"the cached site is damaged \(site.blend differs from its recorded sha256"):
        obs2, info = env.reset(seed=on_site)
    env.close()
    assert info["scene"] == ENTRY
    assert np.array_equal(obs2["depth"], obs["depth"]) and np.array_equal(obs2["label"], obs["label"])


def test_a_stale_entry_of_ours_is_replaced_without_a_warning(cache, monkeypatch):
    import generator.envs.scenes as scenes

    monkeypatch.setattr(scenes, "site_code_key", lambda: "f" * 64)  # the site generator changed since
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        spec = site_scene(3, "small", cache)
    assert json.loads((cache / ENTRY / "scene.json").read_text())["code_key"] == "f" * 64
    assert spec.blend == cache / ENTRY / "site.blend"


# ---- item i: what killed builds leave --------------------------------------------------------
def killed_build(cache_dir: Path) -> Path:
    """Start building seed 3 into ``cache_dir`` in another process and kill it (SIGKILL) once
    its temporary folder holds a file with some bytes in it; returns that folder."""
    code = f"import sys; sys.path.insert(0, {str(ROOT)!r}); from generator.envs.scenes import site_scene; " \
           f"site_scene(3, 'small', {str(cache_dir)!r})"
    env = {k: v for k, v in os.environ.items() if k != "OCIO"}
    proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            for folder in cache_dir.glob(f".{ENTRY}-*"):
                try:
                    if any(p.stat().st_size > 0 for p in folder.iterdir()):
                        return folder
                except FileNotFoundError:  # renamed into place meanwhile
                    pass
            time.sleep(0.02)
        raise AssertionError(f"no temporary folder with a file appeared in {cache_dir} (exit {proc.poll()})")
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()


def test_leftovers_of_killed_builds_are_removed_under_the_entry_lock(built, tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    killed = killed_build(cache)
    assert killed.is_dir() and not (cache / ENTRY).exists()
    shutil.copytree(built, cache / ENTRY)  # the entry, as another process would have built it since
    old = cache / f".{ENTRY}-0123456789ab-old"  # an entry being replaced when its build was killed
    shutil.copytree(built, old)
    kept = {cache / f".{ENTRY}-abcdef012345": "no marker",  # a user's folder, named as a leftover
            cache / f".{ENTRY}-backup": "a copy of an entry with another name",
            cache / f".{ENTRY}-x1y2z3w4": "a leftover of a build before markers"}
    for folder in kept:
        shutil.copytree(built, folder)
    for folder in (cache / f".{ENTRY}-abcdef012345", cache / f".{ENTRY}-x1y2z3w4"):
        (folder / ".buildee-site-cache").unlink(missing_ok=True)
    with open(cache / f".{ENTRY}.lock", "a") as lock:  # a build of this entry under way elsewhere
        fcntl.flock(lock, fcntl.LOCK_EX)
        site_scene(3, "small", cache)
        assert killed.is_dir() and old.is_dir()  # the running build's folder is never touched
    site_scene(3, "small", cache)
    assert not killed.exists() and not old.exists()
    assert all(folder.is_dir() for folder in kept), kept
    assert tree(cache / ENTRY) == tree(built)
