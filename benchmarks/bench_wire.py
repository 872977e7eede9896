"""Loopback publish -> listen (issue: RflySim wire compatibility).

10 s of the default preset at 10x real time (1 million rays) sent over UDP on
127.0.0.1 to a ``livox-viz listen`` process that records what it decodes;
checks that no frame was lost and that the decoded points equal the
publisher's own (``livox-viz scan`` with the same arguments), prints the
receiver's CPU time per frame, then the sustained rate when unpaced.
"""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from livox_viz.cli import main as cli


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def run(seconds: float, speed: str, folder: Path) -> tuple[float, str]:
    port = free_port()
    frames = round(seconds * 10)
    record = folder / f"received-{speed}.npz"
    listener = subprocess.Popen(
        [sys.executable, "-m", "livox_viz", "listen", "--host", "127.0.0.1", "--port", str(port),
         "--frames", str(frames), "--timeout", "30", "--record", str(record)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # Start sending once it listens (a fixed pause lost every frame when start-up took longer on a busy machine).
    assert "listening on" in listener.stderr.readline()
    start = time.perf_counter()
    extra = ["--unpaced"] if speed == "unpaced" else ["--speed", speed]
    cli(["publish", "--to", f"127.0.0.1:{port}", "--seconds", str(seconds), *extra])
    wall = time.perf_counter() - start
    out, _ = listener.communicate(timeout=120)
    return wall, out + f"\nrecord={record}"


def main() -> None:
    seconds = 10.0
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        reference = folder / "scan.npz"
        cli(["scan", "--seconds", str(seconds), "--out", str(reference)])
        want = np.load(reference)
        for speed in ("10", "unpaced"):
            wall, out = run(seconds, speed, folder)
            got = np.load(re.search(r"record=(\S+)", out).group(1))
            frames = len(np.unique(got["frame"]))
            identical = np.array_equal(got["xyz_int16"], want["xyz_int16"]) and np.array_equal(
                got["xyz_sensor"], want["xyz_sensor"])
            cpu = re.search(r"receiver CPU ([\d.]+) ms per frame", out)
            print(f"{speed:>8}: {seconds:g} s of scan ({len(want['frame']):,} returns of 1,000,000 rays) in "
                  f"{wall:.2f} s = {seconds / wall:.1f} x real time; frames received {frames}/100; "
                  f"decoded points identical: {identical}; receiver CPU {cpu.group(1) if cpu else '?'} ms/frame")


if __name__ == "__main__":
    main()
