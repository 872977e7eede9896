"""``fit RECORDING``'s figures (issue 44): known answers from made frames, and real frames when given.

1. Made frames (a known answer): each shipped head's track turned into an image,
   its lasers maybe reversed, started at another laser and phase, its motors off
   by a few hundred ppm, with 0.02 deg of angular noise and 25 % no-returns, 0.1 s.
   Printed: what the fit found against the truth, the median per 2 ms window, the
   residual at random phases, and the fit's time next to making the frame's
   pattern in the same run (the reference).
2. With ``--real DIR`` (frames recorded by real sensors, PCD in firing order):
   each frame fitted with the head guessed, the same figures.

    .venv/bin/python benchmarks/bench_recording_fit.py [--real /path/to/real/frames]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from livox_viz import load_preset
from livox_viz.files.frame_files import read_frame_rows
from livox_viz.fitting.recording_fit import RecordedFrame, fit_recording, head_likeness, imaged_config
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.planes import directions_from_xy

CASES = (("livox_tele15", "mirrored left-right", False, (-1500.0, -1570.0)),
         ("livox_horizon", "turned 180 degrees", False, (2150.0, 2250.0)),
         ("livox_avia", "as printed", True, (600.0, -900.0)),
         ("livox_mid360", "mirrored left-right", False, (-700.0, 400.0)))


def made(preset: str, image: str, reverse: bool, ppm: tuple[float, float], seed: int = 7):
    config = imaged_config(load_preset(preset), image, reverse)
    params = config.risley if config.pattern_model == "risley" else config.track
    hz_name = "prism_hz" if config.pattern_model == "risley" else "base_hz"
    moved = dataclasses.replace(params, **{hz_name: tuple(f * (1 + 1e-6 * p) for f, p in
                                                          zip(getattr(params, hz_name), ppm, strict=True))},
                                phase_rad=tuple(v + d for v, d in zip(params.phase_rad, (1.1, -0.4), strict=True)))
    sensor = dataclasses.replace(config, **{config.pattern_model: moved})
    rng = np.random.default_rng(seed)
    count = round(0.1 * sensor.point_rate)
    started = time.perf_counter()
    xy = make_pattern(sensor).points(2, count).xy_deg.copy()
    making = time.perf_counter() - started
    rays = directions_from_xy(xy + rng.normal(0, 0.02, xy.shape), sensor.pattern_plane)
    rays[rng.random(count) < 0.25] = 0.0
    return RecordedFrame(f"made {preset}", rays), making


def report(label: str, fit, seconds: float, reference: str) -> None:
    print(f"  {label:34s} {fit.image:20s} lasers {fit.laser_order:15s} first {fit.first_laser}  ppm "
          f"{fit.ppm[0]:+6.0f} {fit.ppm[1]:+6.0f}  window median {np.median(fit.window_median_deg):.4f} deg "
          f"(max {fit.window_median_deg.max():.3f}, re-aligned {np.nanmedian(fit.window_aligned_deg):.4f})  random "
          f"{fit.random_median_deg:.2f} deg  fit {seconds:.1f} s ({reference})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--real", type=Path, help="a folder of real frames (*.pcd)")
    args = parser.parse_args()
    print("made frames (truth: image, reversed, ppm; 0.02 deg noise, 25 % no-returns, 0.1 s):")
    for preset, image, reverse, ppm in CASES:
        frame, making = made(preset, image, reverse, ppm)
        started = time.perf_counter()
        fit = fit_recording(load_preset(preset), frame)
        print(f" {preset}: truth {image}, reversed {reverse}, ppm {ppm[0]:+.0f} {ppm[1]:+.0f}")
        report("found", fit, time.perf_counter() - started, f"making its pattern {making * 1000:.0f} ms")
    if args.real is None:
        return
    print(f"real frames in {args.real}:")
    heads = ("livox_tele15", "livox_horizon", "livox_mid360", "livox_avia", "livox_hap", "livox_mid40_risley",
             "livox_mid70_risley")
    for path in sorted(args.real.glob("*.pcd")):
        rows = read_frame_rows(path)
        frame = RecordedFrame(path.stem, rows.frd)
        started = time.perf_counter()
        ranked = sorted((head_likeness(load_preset(name), frame), name) for name in heads)
        guessed = time.perf_counter() - started
        config = load_preset(ranked[0][1])
        cut = RecordedFrame(path.stem, rows.frd[:round(0.1 * config.point_rate)])
        started = time.perf_counter()
        fit = fit_recording(config, cut)
        report(f"{path.stem[:20]} as {ranked[0][1]}", fit, time.perf_counter() - started,
               f"head guessed in {guessed:.1f} s")


if __name__ == "__main__":
    main()
