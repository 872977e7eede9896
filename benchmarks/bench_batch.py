"""``livox-viz batch`` throughput: the same spec on the local pool of processes and on a Dask LocalCluster.

A spec of ``JOBS`` scans of a few seconds each (two sensors, two scenes, a flight, seeds) into ``.npz`` is run
three ways in the same run, each into a fresh folder and interleaved over rounds: the local pool (one process
a core), a Dask ``LocalCluster`` of as many processes (``--dask local:N``), and the same scans one after the
other as single ``scan`` commands (the reference a user without ``batch`` has). Each figure is jobs per minute
and points per second of the whole command, start-up included (the pool's and the cluster's too), best of
the rounds.

Usage: ``bench_batch.py [--rounds N] [--seconds S] [--seeds K]``.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from livox_viz.cli.batch_spec import read_spec, scan_argv
from livox_viz.core.portable import usable_cores

SPEC = """seconds = {seconds}
[grid]
sensors = ["livox_mid70", "livox_mid40"]
scenes = ["urban", "open_field"]
trajectories = ["line"]
seeds = {seeds}
returns = ["ideal"]
outputs = ["npz"]
"""


def run(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "livox_viz", *argv], check=True, capture_output=True)
    return time.perf_counter() - start


def points(folder: Path) -> int:
    with open(folder / "manifest.csv", newline="") as handle:
        return sum(int(row["points"]) for row in csv.DictReader(handle))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    cores = usable_cores()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        spec = folder / "spec.toml"
        spec.write_text(SPEC.format(seconds=args.seconds, seeds=list(range(args.seeds))))
        jobs = read_spec(spec)
        best = {"local": float("inf"), "dask": float("inf"), "one by one": float("inf")}
        total = 0
        for round_ in range(args.rounds):
            for how in best:
                out = folder / f"{how.replace(' ', '_')}{round_}"
                if how == "one by one":
                    out.mkdir()
                    start = time.perf_counter()
                    for job in jobs:
                        run(scan_argv(job, out, None))
                    best[how] = min(best[how], time.perf_counter() - start)
                    continue
                extra = ["--dask", f"local:{cores}"] if how == "dask" else []
                best[how] = min(best[how], run(["batch", str(spec), "--out", str(out), *extra]))
                total = points(out)
        print(f"batch of {len(jobs)} jobs of {args.seconds:g} s of scan ({total:,} points), {cores} cores, best of "
              f"{args.rounds} rounds, start-up included:")
        for how, seconds in best.items():
            where = {"local": f"local pool of {cores} processes", "dask": f"Dask LocalCluster of {cores} processes",
                     "one by one": "single scan commands one after the other"}[how]
            print(f"  {where:42s} {seconds:6.1f} s: {len(jobs) / seconds * 60:5.1f} jobs/min, "
                  f"{total / seconds:,.0f} points/s ({best['one by one'] / seconds:.2f} x one by one)")


if __name__ == "__main__":
    main()
