"""Pattern generation speed and memory (issue: the scan-pattern core).

Prints the default preset's generation rate (xy in degrees and times, frame by
frame) as a multiple of the sensor's own 100 000 points/s, next to numpy.copy of
arrays of the same size in the same run, and the resident memory over a 60 s
stream taken frame by frame.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import best_of, rss_mib

from livox_viz import ScanPattern, load_preset


def main() -> None:
    cfg = load_preset("livox_mid70")
    seconds = 60
    frames = seconds * cfg.data_check_freq
    points = frames * cfg.points_per_frame

    def generate() -> None:
        pattern = ScanPattern(cfg, seed=0)
        for _ in range(frames):
            pattern.next_frame()

    xy = np.random.default_rng(0).random((cfg.points_per_frame, 2))
    t = np.random.default_rng(1).random(cfg.points_per_frame)

    def copy_same_size() -> None:
        for _ in range(frames):
            np.copy(xy)
            np.copy(t)

    ours = best_of(generate, 5)
    copy = best_of(copy_same_size, 5)
    rate = points / ours
    print(f"pattern generation, default preset, {seconds} s of scan = {points:,} points, frame by frame")
    print(f"  ours:        {ours * 1e3:8.1f} ms  {rate / 1e6:8.1f} M points/s "
          f"= {rate / cfg.point_rate:7.0f} x real time")
    print(f"  numpy.copy:  {copy * 1e3:8.1f} ms  {points / copy / 1e6:8.1f} M points/s (same arrays, same frames)")
    print(f"  ours / copy: {ours / copy:8.2f} x the time of a bare copy (target: >= 500 x real time)")

    pattern = ScanPattern(cfg, seed=0)
    samples = []
    for frame in range(frames):
        pattern.next_frame()
        if frame % cfg.data_check_freq == 0:
            samples.append(rss_mib())
    growth = samples[-1] - samples[1]
    print(f"memory over a {seconds} s stream: RSS {samples[1]:.1f} MiB after 1 s, {samples[-1]:.1f} MiB after "
          f"{seconds} s (growth {growth:+.2f} MiB; flat means no growth per frame)")


if __name__ == "__main__":
    main()
