"""The track model's figures (issue 18: every Livox sensor built in).

1. Fit: ``fit_track`` on each table (the shipped ones; with ``--tables DIR`` also
   the public 4 s Horizon, Mid-360, Avia and Tele-15 tables), its time (target <= 30 s) next to
   reading the table in the same run, and its residual (rms, p95, max of the angle
   between each row's ray and the model's; target rms <= 0.01 deg).
2. Stream: every sensor preset frame by frame as a multiple of real time, against
   the seed's rosette making the same number of points in the same run
   (interleaved, best of each: the machine is shared).

    .venv/bin/python benchmarks/bench_track.py [--tables /path/to/public/tables]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import best_of

from livox_viz import load_preset, make_pattern
from livox_viz.fitting.reference import load_reference
from livox_viz.fitting.track_fit import fit_track

RATES = {"mid40": 100_000, "mid70": 100_000, "horizon": 240_000, "mid360": 200_000, "avia": 240_000,
         "tele15": 240_000}
PRESETS = ("livox_mid40_risley", "livox_mid70_risley", "livox_avia", "livox_tele15", "livox_horizon", "livox_hap",
           "livox_mid360")


def fits(tables: Path | None) -> None:
    sources: list[tuple[str, str, float | None]] = [(name, name, None) for name in RATES]
    if tables is not None:
        sources += [(f"{name} (public 4 s)", str(tables / f"{name}.npy"), RATES[name])
                    for name in ("horizon", "mid360", "avia", "tele15") if (tables / f"{name}.npy").is_file()]
    print("fit_track, default tolerance 0.001 deg (angle between rays, every row):")
    for label, source, rate in sources:
        start = time.perf_counter()
        table = load_reference(source, rate=rate)
        read = time.perf_counter() - start
        fit = fit_track(table)
        params = fit.params
        print(f"  {label:22s} {len(table.t):>9,} rows, {params.lasers} laser(s), {params.form:5s} "
              f"{len(params.terms):3d} terms: rms {fit.rms_deg:.2e}, p95 {fit.p95_deg:.2e}, max {fit.max_deg:.2e} deg; "
              f"fitted in {fit.seconds:.1f} s (reading the table {read:.2f} s; target <= 30 s)")


def streams(seconds: int = 5) -> None:
    rosette = load_preset("livox_mid70")

    def run(config, frames: int) -> None:
        stream = make_pattern(config, 0)
        for _ in range(frames):
            stream.next_frame()

    print(f"stream, frame by frame, {seconds} s of each preset against the seed rosette making as many points:")
    for name in PRESETS:
        config = load_preset(name)
        frames = seconds * config.data_check_freq
        points = frames * config.points_per_frame
        # The rosette makes the same number of points (its frames are 10 000 points).
        rosette_frames = points // rosette.points_per_frame
        ours, reference = float("inf"), float("inf")
        for _ in range(3):
            ours = min(ours, best_of(lambda config=config, frames=frames: run(config, frames), 1))
            reference = min(reference, best_of(lambda count=rosette_frames: run(rosette, count), 1))
        terms = len(config.series.terms)
        print(f"  {name:20s} {config.point_rate:>7,} pts/s, {config.lasers} laser(s), {terms:3d} terms: "
              f"{seconds / ours:7.0f} x real time; the rosette, the same {points:,} points: "
              f"{points / rosette.point_rate / reference:6.0f} x its real time -> {ours / reference:5.1f} x its time")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tables", type=Path, help="folder of the public 4 s horizon.npy and mid360.npy")
    args = parser.parse_args()
    fits(args.tables)
    streams()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
