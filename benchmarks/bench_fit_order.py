"""Fitting tables out of laser order (issue 33 §3): the time it costs, against the same fit in order.

For each shipped table, over the same span of firings (an odd length, most of the table), in the same run:

- **in order**: ``fit_track`` on the shipped rows (every firing, lasers in one fixed order);
- **out of order**: the same firings with the lasers fired in a drifting order and thinned by 20 % random
  drops, each kept row with its time (``tests/made_tables.py``: every laser's own rows interpolated to the
  slot it now fires at); a one-laser table is only thinned.

Each line gives both fit times (wall clock and this process's CPU, the faster of ``--rounds`` runs each,
interleaved) and the out-of-order fit's residual against the in-order table's track (the angle between
rays, laser for laser). Then the bad inputs (noise, one constant row, rows of two heads interleaved, a NaN):
the time to their one-line refusal. The machine is shared: the lead re-runs this on a quiet one.

    .venv/bin/python benchmarks/bench_fit_order.py [--rounds N]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from livox_viz.core.errors import LivoxVizError  # noqa: E402
from livox_viz.fitting.reference import ReferencePattern, load_reference, xy_from_zup  # noqa: E402
from livox_viz.fitting.track_fit import TrackFit, fit_track  # noqa: E402
from livox_viz.patterns.planes import angle_between_deg  # noqa: E402
from livox_viz.patterns.track import track_xy  # noqa: E402
from tests.made_tables import out_of_order  # noqa: E402

LASERS = {"mid40": 1, "mid70": 1, "horizon": 6, "mid360": 4, "avia": 6, "tele15": 6}


def timed(table: ReferencePattern) -> tuple[TrackFit, float, float]:
    """The fit, its wall time and its CPU time (seconds)."""
    wall, cpu = time.perf_counter(), time.process_time()
    fit = fit_track(table)
    return fit, time.perf_counter() - wall, time.process_time() - cpu


def against_track(fit: TrackFit, source: ReferencePattern, first: int, last: int) -> float:
    """Rms angle (deg) between the in-order table's rows of firings ``first .. last`` and the fitted series, each
    shipped laser held against the fitted laser whose series is nearest (the fit names its lasers by offset)."""
    lasers = fit.params.lasers
    firing = np.arange(first, last + 1)
    squares = []
    for k in range(lasers):
        mine = firing[firing % lasers == k]
        times = (mine - first) / source.rate
        theirs = source.xy_deg[mine]
        best = min(float(np.mean(angle_between_deg(track_xy(fit.params, times, np.full(mine.size, j),
                                                            panorama=source.plane == "panorama"),
                                                   theirs, source.plane) ** 2)) for j in range(lasers))
        squares.append(best * mine.size)
    return float(np.sqrt(sum(squares) / firing.size))


def made_tables(name: str, source: ReferencePattern, seed: int) -> tuple[ReferencePattern, ReferencePattern, int, int]:
    """The span's rows in order, the same span out of order and thinned, and the span's first and last firing."""
    start = len(source.t) // 17
    rows = len(source.t) - 2 * start - 1  # an odd length, inside the table (the interpolation needs its ends)
    rows -= 1 - rows % 2
    made = out_of_order(name, LASERS[name], source.rate, rows, seed=seed, drop=0.2, start=start)
    first, last = int(made.slot[0]), int(made.slot[-1])
    xy, plane = xy_from_zup(made.angles[:, 0], made.angles[:, 1])
    shuffled = ReferencePattern(f"{name} out of order", xy, (made.slot - first) / source.rate, source.rate, plane,
                                "its t column")
    span = slice(first, last + 1)
    in_order = ReferencePattern(name, source.xy_deg[span], np.arange(last + 1 - first) / source.rate, source.rate,
                                source.plane, source.rate_source)
    return in_order, shuffled, first, last


def bad_inputs() -> None:
    rng = np.random.default_rng(9)
    horizon = load_reference("horizon")
    avia = load_reference("avia")
    mixed = horizon.xy_deg[:120_000].copy()
    mixed[1::2] = avia.xy_deg[1:120_000:2]
    nan = horizon.xy_deg[:120_000].copy()
    nan[4321, 1] = np.nan
    t = np.arange(120_000) / 240_000.0
    cases = {"noise": rng.uniform(-20, 20, (120_000, 2)), "one constant row": np.tile([[3.0, 1.0]], (120_000, 1)),
             "Horizon and Avia rows interleaved": mixed, "a NaN in the Horizon": nan}
    print("bad input, 120 000 rows at 240 000 rows/s: the time to the one-line refusal")
    for label, xy in cases.items():
        start = time.perf_counter()
        try:
            fit_track(ReferencePattern(label, xy, t, 240_000.0))
            said = "FITTED (should have been refused)"
        except LivoxVizError as exc:
            said = str(exc)[:110] + "..."
        print(f"  {label:34s} {time.perf_counter() - start:5.1f} s  {said}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=1)
    args = parser.parse_args()
    print(f"fit_track on 2 cores (default tolerance), best of {args.rounds}; out of order = drifting laser order, "
          "20 % of rows dropped; both over the same odd span of firings:")
    for name in LASERS:
        source = load_reference(name)
        ordered, shuffled, first, last = made_tables(name, source, seed=1)
        best: dict[str, tuple[float, float]] = {}
        results: dict[str, TrackFit] = {}
        for _ in range(args.rounds):
            for label, table in (("in order", ordered), ("out of order", shuffled)):
                fit, wall, cpu = timed(table)
                results[label] = fit
                old = best.get(label, (np.inf, np.inf))
                best[label] = (min(old[0], wall), min(old[1], cpu))
        (wall_in, cpu_in), (wall_out, cpu_out) = best["in order"], best["out of order"]
        fit = results["out of order"]
        recovered = against_track(fit, source, first, last)
        print(f"  {name:8s} in order {len(ordered.t):>9,} rows {wall_in:6.1f} s (CPU {cpu_in:5.1f}); out of order "
              f"{len(shuffled.t):>9,} rows {wall_out:6.1f} s (CPU {cpu_out:5.1f}): {wall_out / wall_in:4.2f} x; "
              f"{fit.params.lasers} lasers, {fit.relabelled} rows moved, rms {fit.rms_deg:.1e} deg, "
              f"{recovered:.1e} deg from the in-order track")
    bad_inputs()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
