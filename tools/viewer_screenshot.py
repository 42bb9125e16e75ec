"""Screenshot of a Rerun recording in the Rerun web viewer, with headless Chromium (for docs/viewer.md).

Serves the recording with ``rerun --web-viewer`` on 127.0.0.1, opens it in headless Chromium
(software WebGL: SwiftShader), waits for the viewer to load and render, optionally moves the
time cursor (by pressing keys), and saves a PNG through the DevTools protocol (a minimal
WebSocket client, standard library only). Nothing leaves the machine: both servers listen on
127.0.0.1 and Chromium runs with its background networking off. Both run in their own process
group, stopped as a whole at the end (the ``rerun`` wrapper's viewer binary included); a port
already in use is refused (exit 2) rather than screenshotting whatever serves there.

Usage: .venv/bin/python tools/viewer_screenshot.py seed0.rrd docs/images/viewer_seed0.png
       [--size 1600x1000] [--wait 60] [--keys ArrowRight*20]
"""

from __future__ import annotations

import argparse
import base64
import json
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path


class DevTools:
    """Just enough of a WebSocket client (RFC 6455, text frames) to talk to one Chromium page."""

    def __init__(self, ws_url: str):
        host_port, path = ws_url.removeprefix("ws://").split("/", 1)
        host, port = host_port.split(":")
        self.sock = socket.create_connection((host, int(port)), timeout=120)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET /{path} HTTP/1.1\r\nHost: {host_port}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
        head = b""
        while b"\r\n\r\n" not in head:
            head += self.sock.recv(1)
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise RuntimeError(f"DevTools refused the WebSocket: {head[:100]!r}")
        self.next_id = 0

    def _recv_exact(self, n: int) -> bytes:
        data = b""
        while len(data) < n:
            part = self.sock.recv(n - len(data))
            if not part:
                raise RuntimeError("DevTools closed the connection")
            data += part
        return data

    def _recv_message(self) -> dict:
        payload = b""
        while True:
            b0, b1 = self._recv_exact(2)
            n = b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._recv_exact(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._recv_exact(8))[0]
            payload += self._recv_exact(n)
            if b0 & 0x80:  # final fragment
                return json.loads(payload)

    def call(self, method: str, **params) -> dict:
        self.next_id += 1
        body = json.dumps({"id": self.next_id, "method": method, "params": params}).encode()
        mask = os.urandom(4)
        n = len(body)
        head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack(">H", n)
                                if n < 65536 else bytes([0x80 | 127]) + struct.pack(">Q", n))
        self.sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(body)))
        while True:  # skip events until our answer
            msg = self._recv_message()
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})


def wait_for(url: str, seconds: float) -> None:
    end = time.time() + seconds
    while time.time() < end:
        try:
            urllib.request.urlopen(url, timeout=2).read(1)
            return
        except OSError:
            time.sleep(0.5)
    raise RuntimeError(f"{url} did not answer within {seconds} s")


def press(tab: DevTools, key: str, times: int) -> None:
    for _ in range(times):
        for kind in ("keyDown", "keyUp"):
            tab.call("Input.dispatchKeyEvent", type=kind, key=key, code=key,
                     windowsVirtualKeyCode={"ArrowRight": 39, "ArrowLeft": 37, "Home": 36}.get(key, 0))
        time.sleep(0.2)


def port_taken(port: int) -> bool:
    """Whether something listens on 127.0.0.1:``port`` (or on every interface at that port)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # a closed connection in TIME_WAIT is not a listener
        try:
            probe.bind(("127.0.0.1", port))
        except OSError:
            return True
    return False


def start(command: list[str]) -> subprocess.Popen:
    """``command`` in its own process group (session), so that stopping it stops what it starts
    (``.venv/bin/rerun`` is a Python wrapper that runs the ``rerun_cli/rerun`` binary)."""
    return subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)


def stop(proc: subprocess.Popen, seconds: float = 20) -> None:
    """SIGTERM to ``proc``'s whole process group, SIGKILL to what is left after ``seconds``."""
    try:
        os.killpg(proc.pid, signal.SIGTERM)
    except ProcessLookupError:
        pass
    try:
        proc.wait(timeout=seconds)
    except subprocess.TimeoutExpired:
        pass
    end = time.time() + seconds
    while time.time() < end:  # the group outlives its leader while a child still runs
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.2)
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait()


def fail(message: str) -> None:
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("rrd", type=Path)
    p.add_argument("png", type=Path)
    p.add_argument("--size", default="1600x1000")
    p.add_argument("--wait", type=float, default=60, help="seconds to let the viewer load and render")
    p.add_argument("--keys", nargs="*", default=[], help="keys to press before the screenshot, e.g. ArrowRight*20")
    p.add_argument("--web-port", type=int, default=9090)
    p.add_argument("--grpc-port", type=int, default=9877)
    p.add_argument("--debug-port", type=int, default=9222)
    args = p.parse_args()
    width, height = (int(v) for v in args.size.split("x"))
    if not args.rrd.is_file():
        fail(f"{args.rrd}: no such file; write one with python -m datasets.view")
    for option, port in (("--web-port", args.web_port), ("--grpc-port", args.grpc_port),
                         ("--debug-port", args.debug_port)):
        if port_taken(port):  # else the page could show what an older viewer still serves there
            fail(f"{option} {port}: 127.0.0.1:{port} is already in use (a viewer or browser left running?); "
                 f"stop it, or choose another {option}")
    rerun = Path(sys.executable).with_name("rerun")
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        fail("no chromium here; apt-get install chromium")
    procs, profile = [], None
    # a SIGTERM (e.g. from `timeout`) must still stop the viewer and the browser below
    signal.signal(signal.SIGTERM, lambda *_: sys.exit("error: terminated"))
    try:
        procs.append(start([str(rerun), "--web-viewer", "--bind", "127.0.0.1", "--web-viewer-port",
                            str(args.web_port), "--port", str(args.grpc_port), str(args.rrd)]))
        wait_for(f"http://127.0.0.1:{args.web_port}/", 30)
        url = (f"http://127.0.0.1:{args.web_port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{args.grpc_port}%2Fproxy")
        profile = tempfile.mkdtemp(prefix="chromium-")
        procs.append(start([chromium, "--headless", "--no-sandbox", "--disable-quic", "--no-first-run",
                            "--disable-background-networking", "--disable-component-update",
                            "--disable-sync", f"--user-data-dir={profile}", "--use-angle=swiftshader",
                            "--enable-unsafe-swiftshader", f"--window-size={width},{height}",
                            f"--remote-debugging-port={args.debug_port}", "--remote-allow-origins=*",
                            "about:blank"]))
        wait_for(f"http://127.0.0.1:{args.debug_port}/json/version", 30)
        pages = json.load(urllib.request.urlopen(f"http://127.0.0.1:{args.debug_port}/json/list"))
        tab = DevTools(next(pg for pg in pages if pg["type"] == "page")["webSocketDebuggerUrl"])
        tab.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1, mobile=False)
        tab.call("Page.navigate", url=url)
        time.sleep(args.wait)
        for spec in args.keys:
            key, _, times = spec.partition("*")
            press(tab, key, int(times or 1))
        if args.keys:
            time.sleep(min(20.0, args.wait / 2))
        shot = tab.call("Page.captureScreenshot", format="png")
        args.png.write_bytes(base64.b64decode(shot["data"]))
        print(args.png)
    finally:
        for proc in reversed(procs):
            stop(proc)
        if profile is not None:
            shutil.rmtree(profile, ignore_errors=True)


if __name__ == "__main__":
    main()
