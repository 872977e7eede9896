"""``livox-viz batch`` throughput: the same spec on the local pool of processes and on a Dask LocalCluster.

A spec of ``JOBS`` scans of a few seconds each (two sensors, two scenes, a flight, seeds) into ``.npz`` is run
three ways in the same run, each into a fresh folder and interleaved over rounds: the local pool (one process
a core), a Dask ``LocalCluster`` of as many processes (``--dask local:N``), and the same scans one after the
other as single ``scan`` commands (the reference a user without ``batch`` has). Each figure is jobs per minute
and points per second of the whole command, start-up included (the pool's and the cluster's too), best of
the rounds.

``--huge N`` measures instead a grid of N jobs (``--force``) of 0.05 s scans, stopped (Ctrl-C) once
``--finished`` jobs have finished: the time from the command's start to its first job's start (the job's
folder made) and end (its ``job.json``), and the batch process's peak memory (its own VmHWM from Linux's
``/proc``, the pool's processes not included: they are the same whatever the grid). With ``--against REF``
the same is measured, in the same run, for the code of git revision REF (say ``origin/main``: today's), run
from an exported copy of its ``livox_viz`` and ``presets``; this code's batch is also run again in its folder
(the resume: finished jobs skipped, ``--finished`` more run).

Usage: ``bench_batch.py [--rounds N] [--seconds S] [--seeds K]``,
``bench_batch.py --huge 1000000 [--finished 3] [--against origin/main]``.
"""

from __future__ import annotations

import argparse
import csv
import os
import signal
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


HUGE_SPEC = """seconds = 0.05
[grid]
sensors = ["livox_mid70"]
scenes = ["urban"]
trajectories = ["none", "hover", "line", "circle", "figure8"]
seeds = {seeds}
returns = ["ideal"]
outputs = {outputs}
"""


def peak_rss(pid: int) -> int | None:
    """The process's peak resident memory in bytes (Linux's VmHWM), None where there is no /proc."""
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None


def huge_run(spec: Path, out: Path, finished: int, code: Path | None) -> dict[str, float | None]:
    """One ``batch --force`` of the spec, stopped by Ctrl-C once ``finished`` jobs have finished."""
    jobs = out / "jobs"
    before = {entry.name for entry in os.scandir(jobs)} if jobs.is_dir() else set()
    environment = dict(os.environ)
    if code is not None:
        environment["PYTHONPATH"] = str(code)
    else:
        environment["PYTHONPATH"] = str(Path(__file__).resolve().parent.parent)
    start = time.perf_counter()
    process = subprocess.Popen([sys.executable, "-m", "livox_viz", "batch", str(spec), "--out", str(out), "--force",
                                "--jobs", "1"], env=environment, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               cwd=out.parent)  # not this checkout's folder: python -m imports from there first
    first_start = first_end = None
    peak = None
    while process.poll() is None:
        names = [entry.name for entry in os.scandir(jobs) if entry.name not in before] if jobs.is_dir() else []
        if names and first_start is None:
            first_start = time.perf_counter() - start
        ended = sum((jobs / name / "job.json").exists() for name in names[:finished + 8])
        if ended and first_end is None:
            first_end = time.perf_counter() - start
        peak = peak_rss(process.pid) or peak
        if ended >= finished:
            break
        time.sleep(0.05)
    peak = peak_rss(process.pid) or peak
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=600)
    if first_end is None:
        sys.exit(f"the batch ended before its first job did: {err.decode(errors='replace')[-2000:]}")
    return {"start": first_start, "end": first_end, "peak": peak, "seconds": time.perf_counter() - start}


def huge(args: argparse.Namespace) -> None:
    outputs = ["npz", "ply", "pcd", "las", "csv"]
    seeds = -(-args.huge // (len(outputs) * 5))  # five trajectories
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        spec = folder / "huge.toml"
        spec.write_text(HUGE_SPEC.format(seeds=list(range(seeds)), outputs=outputs).replace("'", '"'))
        count = seeds * len(outputs) * 5
        codes: dict[str, Path | None] = {"this code": None}
        if args.against:
            reference = folder / "reference"
            reference.mkdir()
            archive = subprocess.run(["git", "archive", args.against, "livox_viz", "presets"], check=True,
                                     capture_output=True, cwd=Path(__file__).resolve().parent.parent).stdout
            subprocess.run(["tar", "-x", "-C", str(reference)], input=archive, check=True)
            codes[args.against] = reference
        print(f"batch --force of {count:,} jobs of 0.05 s, stopped after {args.finished} finished, --jobs 1:")
        runs = [(name, code, folder / f"out-{number}") for number, (name, code) in enumerate(codes.items())]
        # This code's rerun in its folder: the finished jobs skipped through the manifest's index and their records.
        runs.insert(1, ("this code, rerun", None, folder / "out-0"))
        for name, code, out in runs:
            got = huge_run(spec, out, args.finished, code)

            def seconds(value: float | None) -> str:
                return "never" if value is None else f"{value:6.1f} s"

            peak = "?" if got["peak"] is None else f"{got['peak'] / 2**20:7.0f} MiB"
            print(f"  {name:22s} first job started {seconds(got['start'])}, ended {seconds(got['end'])}; batch "
                  f"process peak RSS {peak}; whole run {seconds(got['seconds'])}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--huge", type=int, help="measure a grid of this many jobs instead (see above)")
    parser.add_argument("--finished", type=int, default=3, help="--huge: jobs finished before the stop")
    parser.add_argument("--against", metavar="REF", help="--huge: also measure git revision REF's code")
    args = parser.parse_args()
    if args.huge:
        huge(args)
        return
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
