"""Livox's own files: how fast LVX2 and LVX 1.1 are written, and that a long scan to LVX2 keeps memory flat.

1. Write speed, points a second: the same frames (cast once, held in memory) written to ``.lvx2`` (a Mid-360)
   and ``.lvx`` (a Horizon, dual returns), each against ``.npz`` of the same frames in the same run (best of 3).
2. ``livox-viz scan --preset livox_mid360 --seconds 600 --out X.lvx2`` in a child process: its peak resident
   memory (VmHWM, the child's own ``ru_maxrss``) and wall time, against the same scan of 60 s in the same run
   (flat memory: the 600 s peak within a few MiB of the 60 s one).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import command_peak_mib

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.files.export import PointCloudWriter
from livox_viz.files.lvx_format import head_for_config
from livox_viz.scene.scenes import open_scene

CAST_SECONDS = 2.0
LONG_SECONDS = 600.0
SHORT_SECONDS = 60.0


def write_rate(frames: list, path: Path, head=None, repeats: int = 3) -> float:
    """Points written a second (the best of ``repeats`` writes of ``frames`` to ``path``)."""
    points = sum(len(frame) for frame in frames)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        with PointCloudWriter(path, livox=head) as writer:
            for frame in frames:
                writer.write(frame)
        best = min(best, time.perf_counter() - start)
    return points / best


def main() -> None:
    scene = open_scene("urban")
    with tempfile.TemporaryDirectory() as tmp:
        for preset, suffix, returns in (("livox_mid360", ".lvx2", "ideal"), ("livox_horizon", ".lvx", "datasheet")):
            cfg = load_preset(preset).with_returns_model(returns)
            frames = list(LidarScanner(cfg, scene.mesh, scene.vehicle_pose, seed=0).frames(CAST_SECONDS))
            points = sum(len(frame) for frame in frames)
            head = head_for_config(suffix, cfg, preset)
            livox = write_rate(frames, Path(tmp) / f"w{suffix}", head)
            npz = write_rate(frames, Path(tmp) / "w.npz")
            size = (Path(tmp) / f"w{suffix}").stat().st_size
            print(f"{preset} ({returns}, {points:,} points of {CAST_SECONDS:g} s): {suffix} {livox / 1e6:.2f} M "
                  f"points/s, .npz {npz / 1e6:.2f} M points/s (same frames, same run: {livox / npz:.2f} x); "
                  f"{suffix} {size / 2**20:.1f} MiB")
        for seconds in (SHORT_SECONDS, LONG_SECONDS):
            out = str(Path(tmp) / f"long{seconds:g}.lvx2")
            peak, wall = command_peak_mib(["scan", "--preset", "livox_mid360", "--returns", "ideal", "--seconds",
                                           str(seconds), "--force", "--out", out])
            print(f"scan --preset livox_mid360 --seconds {seconds:g} --out X.lvx2: peak RSS {peak:.0f} MiB, "
                  f"{wall:.1f} s ({seconds / wall:.1f} x real time), file {Path(out).stat().st_size / 2**30:.2f} GiB")
            Path(out).unlink()


if __name__ == "__main__":
    main()
