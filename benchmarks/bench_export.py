"""A long export streams (issue: scene ray casting): 60 s of the default preset and scene to PLY and NPZ.

Prints the resident memory after 5 s and after 60 s of scan time (flat means
the export does not hold the cloud), and the export speed as a multiple of
real time.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import rss_mib

from livox_viz import load_preset
from livox_viz.export import PointCloudWriter
from livox_viz.scan import LidarScanner
from livox_viz.scene import open_scene

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


if __name__ == "__main__":
    main()
