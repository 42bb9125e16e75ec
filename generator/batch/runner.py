"""Run seeds in worker processes: skip finished ones, redo unfinished ones, never mark a
partial folder complete. bpy-free (workers import it)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from tqdm import tqdm

from exporters import FORMAT_VERSION
from exporters.manifest import read_manifest

from .config import RunConfig


def seed_folder(out: Path, seed: int) -> Path:
    return out / f"seed_{seed:06d}"


def partial_folder(out: Path, seed: int) -> Path:
    return out / f".seed_{seed:06d}.partial"


@dataclass
class SeedResult:
    seed: int
    status: str  # done, skipped, failed
    message: str = ""
    summary: dict = field(default_factory=dict)
    seconds: float = 0.0


def plan_seeds(out: Path, seeds: list[int], cfg: RunConfig, overwrite: bool) -> tuple[list[int], list[SeedResult], list[str]]:
    """(seeds to run, skipped results, messages) and remove what must be redone."""
    todo, skipped, notes = [], [], []
    for seed in seeds:
        final, partial = seed_folder(out, seed), partial_folder(out, seed)
        if partial.exists():
            shutil.rmtree(partial)
            notes.append(f"seed {seed}: unfinished output from an earlier run removed; redoing it")
        manifest = read_manifest(final) if final.exists() else None
        current = manifest is not None and manifest.get("format_version") == FORMAT_VERSION
        if current and not overwrite and manifest.get("config") == cfg.to_dict():
            skipped.append(SeedResult(seed, "skipped", "already complete", manifest.get("summary", {})))
            continue
        if final.exists():
            reason = ("no manifest (incomplete)" if manifest is None else "--overwrite" if overwrite else
                      f"format {manifest.get('format_version')}, now {FORMAT_VERSION}" if not current else
                      "different parameters")
            notes.append(f"seed {seed}: existing folder replaced ({reason})")
            shutil.rmtree(final)
        todo.append(seed)
    return todo, skipped, notes


class _Worker:
    def __init__(self, seed: int, out: Path, cfg: RunConfig, position: int, lock):
        self.seed, self.out, self.lock, self.position = seed, out, lock, position
        self.folder = partial_folder(out, seed)
        env = {k: v for k, v in os.environ.items() if k != "OCIO"}
        self.start_time = time.perf_counter()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "generator.batch.worker", json.dumps(cfg.to_dict()), str(seed), str(self.folder)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True,
            cwd=Path(__file__).resolve().parents[2])
        self.bar = tqdm(total=cfg.frames * len(cfg.trajectories), desc=f"seed {seed} frames", unit="frame",
                        position=position, leave=False, dynamic_ncols=True)
        self.events: list[dict] = []
        self.stderr = ""
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()
        self.err_reader = threading.Thread(target=self._read_err, daemon=True)
        self.err_reader.start()

    def _read(self):
        for line in self.proc.stdout:
            if not line.startswith("@@"):
                continue
            event = json.loads(line[2:])
            self.events.append(event)
            if event["event"] == "frame":
                with self.lock:
                    self.bar.update(1)

    def _read_err(self):
        self.stderr = self.proc.stderr.read()

    def finish(self) -> SeedResult:
        self.reader.join()
        self.err_reader.join()
        self.bar.close()
        seconds = time.perf_counter() - self.start_time
        done = [e for e in self.events if e["event"] == "done"]
        if self.proc.returncode == 0 and done and read_manifest(self.folder) is not None:
            final = seed_folder(self.out, self.seed)
            os.replace(self.folder, final)  # atomic: the folder appears complete or not at all
            return SeedResult(self.seed, "done", "", done[0]["summary"], seconds)
        errors = [e["message"] for e in self.events if e["event"] == "error"]
        cause = errors[0] if errors else (self.stderr.strip().splitlines() or [f"exit code {self.proc.returncode}"])[-1]
        log = self.folder / "error.log"
        where = f" (details: {log})" if log.exists() else ""
        return SeedResult(self.seed, "failed", cause + where, {}, seconds)

    def kill(self):
        try:
            os.killpg(self.proc.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass


def run_seeds(out: Path, seeds: list[int], cfg: RunConfig, workers: int) -> list[SeedResult]:
    """Run ``seeds`` with up to ``workers`` processes at once; returns their results."""
    lock = threading.Lock()
    results: list[SeedResult] = []
    pending = list(seeds)
    running: list[_Worker] = []
    overall = tqdm(total=len(seeds), desc="seeds", unit="seed", position=0, dynamic_ncols=True)
    try:
        while pending or running:
            while pending and len(running) < workers:
                used = {w.position for w in running}
                position = min(p for p in range(1, workers + 2) if p not in used)
                running.append(_Worker(pending.pop(0), out, cfg, position, lock))
            time.sleep(0.2)
            for w in [w for w in running if w.proc.poll() is not None]:
                running.remove(w)
                r = w.finish()
                results.append(r)
                overall.update(1)
                tqdm.write(_one_line(r))
    except KeyboardInterrupt:
        for w in running:
            w.kill()
        for w in running:
            w.proc.wait()
            shutil.rmtree(w.folder, ignore_errors=True)
        overall.close()
        raise
    overall.close()
    return results


def _one_line(r: SeedResult) -> str:
    if r.status == "failed":
        return f"seed {r.seed}: FAILED after {r.seconds:.0f} s: {r.message}"
    s = r.summary
    return (f"seed {r.seed}: {s.get('frames', 0)} frames, {s.get('points', 0):,} points, "
            f"{s.get('visible_tracks', 0):,} visible tracks, {r.seconds:.0f} s")
