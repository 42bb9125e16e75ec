"""A real Ray cluster of several nodes on this machine, on loopback only, for the tests and
the benchmark of the Ray executor (tests/test_ray.py, benchmarks/ray.py).

Each node is a `ray start --block` of the venv's Ray in its own process group, with one CPU
by default. The nodes use 127.0.0.2, 127.0.0.3, ...: Ray replaces 127.0.0.1 and localhost
by the machine's outward address, and takes any other loopback address as given, so every
connection stays on loopback. Ray's token authentication is off for the cluster and for
every run joining it (RAY_ENV): a token left in ~/.ray by another Ray would otherwise be
required by the nodes and not sent by the runs.

Stopping: SIGTERM to each `ray start --block` (it stops its node's processes), then SIGKILL
to the process groups for anything left; ``stop`` returns the processes still alive."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RAY = Path(sys.executable).parent / "ray"
RAY_ENV = {"RAY_AUTH_MODE": "disabled", "RAY_ADDRESS": ""}


def node_ip(k: int) -> str:
    """The loopback address of node ``k`` (0: the head)."""
    return f"127.0.0.{2 + k}"


def env(**extra) -> dict:
    return {k: v for k, v in os.environ.items() if k != "OCIO"} | RAY_ENV | extra


def free_ports(n: int) -> list[int]:
    socks = [socket.socket() for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def processes_of(pgids: set[int], marker: str) -> list[int]:
    """Live processes in the process groups ``pgids`` or whose command line names ``marker``
    (zombies, already dead, are left out)."""
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            stat = (d / "stat").read_text()
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        state, pgid = fields[0], int(fields[2])
        if state != "Z" and (pgid in pgids or marker in cmd):
            found.append(int(d.name))
    return found


def _node_ports() -> list[str]:
    listen, grpc, metrics, runtime_env = free_ports(4)
    return [f"--dashboard-agent-listen-port={listen}", f"--dashboard-agent-grpc-port={grpc}",
            f"--metrics-export-port={metrics}", f"--runtime-env-agent-port={runtime_env}"]


def _start(args: list[str], cpus: int, log: Path) -> subprocess.Popen:
    return subprocess.Popen([str(RAY), "start", "--block", "--disable-usage-stats", f"--num-cpus={cpus}",
                             "--object-store-memory=80000000", *_node_ports(), *args], cwd=ROOT, env=env(),
                            stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True)


def _wait_for_nodes(address: str, count: int, deadline: float) -> None:
    probe = "import ray, sys; ray.init(address=sys.argv[1], logging_level='ERROR'); " \
            "print(sum(n['Alive'] for n in ray.nodes()))"
    while time.time() < deadline:
        r = subprocess.run([sys.executable, "-c", probe, address], capture_output=True, text=True, env=env(),
                           timeout=60)
        if r.stdout.strip() == str(count):
            return
        time.sleep(1.0)
    raise TimeoutError(f"the Ray cluster at {address} did not reach {count} nodes")


@contextmanager
def loopback_cluster(nodes: int = 2, cpus: int = 1):
    """Yields the head's HOST:PORT once ``nodes`` nodes of ``cpus`` CPUs each are up; stops
    them all on exit and raises RuntimeError if any of their processes is left."""
    temp = Path(tempfile.mkdtemp(prefix="bray", dir="/tmp"))  # short: Ray's socket paths have a length limit
    gcs, dashboard = free_ports(2)
    address = f"{node_ip(0)}:{gcs}"
    procs: list[subprocess.Popen] = []
    try:
        procs.append(_start(["--head", f"--node-ip-address={node_ip(0)}", f"--port={gcs}", "--include-dashboard=false",
                             f"--dashboard-port={dashboard}", f"--temp-dir={temp}"], cpus, temp / "node0.log"))
        _wait_for_nodes(address, 1, time.time() + 60)
        for k in range(1, nodes):
            procs.append(_start([f"--address={address}", f"--node-ip-address={node_ip(k)}"], cpus, temp / f"node{k}.log"))
        _wait_for_nodes(address, nodes, time.time() + 60)
        yield address
    finally:
        left = _stop(procs, str(temp))
        subprocess.run(["rm", "-rf", str(temp)])
        if left:
            raise RuntimeError(f"Ray processes left behind: {left}")


def _stop(procs: list[subprocess.Popen], marker: str) -> list[int]:
    pgids = {p.pid for p in procs}
    for p in reversed(procs):  # `ray start --block` stops its node's processes on SIGTERM
        p.terminate()
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            pass
    if processes_of(pgids, marker):  # what did not stop
        for pgid in pgids:
            try:
                os.killpg(pgid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        time.sleep(1.0)
    for p in procs:
        p.wait(timeout=10)
    return processes_of(pgids, marker)
