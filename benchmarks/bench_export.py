"""Long exports stream: memory stays flat however long the scan or pattern.

1. 60 s of the default preset and scene to PLY and NPZ: resident memory after
   5 s and after 60 s of scan time, and the speed as a multiple of real time.
2. ``livox-viz pattern --out X.npz`` for 60 s and 600 s in a child process: its
   peak resident memory (target: flat, not growing with the seconds), next to
   ``livox-viz info`` (the interpreter and imports alone) in the same run.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import rss_mib

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.files.export import PointCloudWriter
from livox_viz.scene.scenes import open_scene

SECONDS = 60.0


def main() -> None:
    cfg = load_preset("livox_mid70")
    scene = open_scene("urban")
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in (".ply", ".npz"):
            path = Path(tmp) / f"long{suffix}"
            scanner = LidarScanner(cfg, scene.mesh, scene.vehicle_pose, seed=0)
            start = time.perf_counter()
            early = None
            with PointCloudWriter(path) as writer:
                for frame in scanner.frames(SECONDS):
                    writer.write(frame)
                    if early is None and frame.index == 50:
                        early = rss_mib()
            wall = time.perf_counter() - start
            late = rss_mib()
            print(f"{suffix}: {writer.count:,} points ({SECONDS:g} s of scan) in {wall:.1f} s = "
                  f"{SECONDS / wall:.0f} x real time; RSS {early:.0f} MiB after 5 s, {late:.0f} MiB after "
                  f"{SECONDS:g} s ({late - early:+.0f} MiB; the file is {path.stat().st_size / 2**20:.0f} MiB)")


def child_peak_mib(argv: list[str], cwd: str) -> tuple[float, float]:
    """Peak RSS (MiB) and wall time of ``livox-viz ARGV`` in a fresh child process.

    The child reports its own VmHWM as it exits: the kernel's resource usage of a child (``wait4``,
    ``RUSAGE_CHILDREN``) keeps the high-water mark of the process it was forked from, here this one's.
    """
    import subprocess

    report = Path(cwd) / "peak-kib"
    code = (
        "import atexit, runpy, sys\n"
        "def peak():\n"
        "    status = open('/proc/self/status').read()\n"
        f"    open({str(report)!r}, 'w').write(status.split('VmHWM:')[1].split()[0])\n"
        "atexit.register(peak)\n"
        f"sys.argv = ['livox-viz', *{argv!r}]\n"
        "runpy.run_module('livox_viz', run_name='__main__', alter_sys=True)\n"
    )
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], cwd=cwd, check=True, capture_output=True)
    wall = time.perf_counter() - start
    return int(report.read_text()) / 1024, wall


def pattern_memory() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        base, _ = child_peak_mib(["info"], tmp)
        print(f"pattern --out .npz, child process peak RSS; 'livox-viz info' alone: {base:.0f} MiB")
        for seconds in (60, 600):
            peak, wall = child_peak_mib(["pattern", "--seconds", str(seconds), "--out", "p.npz"], tmp)
            size = (Path(tmp) / "p.npz").stat().st_size / 2**30
            print(f"  {seconds:4d} s ({seconds * 100_000:,} points, {size:.1f} GiB file): peak {peak:.0f} MiB "
                  f"in {wall:.0f} s (target: flat)")
            (Path(tmp) / "p.npz").unlink()


if __name__ == "__main__":
    main()
    pattern_memory()
