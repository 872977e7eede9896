"""The whole ``scan`` command against the scan loop alone, for every output (issue 34: writing keeps up).

1. Speed: for ``.npz .ply .pcd .las .csv`` and ``--rosbag``, ``livox-viz scan
   --seconds 60`` in a child process, less the same command for 0.1 s (its
   start-up: the interpreter, imports, the scene, numba's cached loops), against
   the scan loop alone (``LidarScanner.frames`` consumed, nothing written) for the
   same 59.9 s in this process, measured in the same rounds: target >= 0.5 x the
   loop's speed on 2 cores. Rounds interleave the loop and the commands; each
   figure is the median of its rounds' ratios (and the best of each beside it).
2. The loop alone at 1 and 2 workers (``--workers``): what a second core gives.
3. Memory (``--long``): the peak RSS of each command for 60 s and 600 s of scan
   (a 10-minute scan), each child's own VmHWM: target flat.

Usage: ``bench_scan_io.py [--preset NAME] [--rounds N] [--seconds S] [--long]``.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import command_peak_mib

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.patterns.stream import points_before
from livox_viz.scene.raycast import EmbreeCaster
from livox_viz.scene.scenes import open_scene

OUTPUTS = (".npz", ".ply", ".pcd", ".las", ".csv", "rosbag")
START_UP_SECONDS = 0.1


def loop_seconds(preset: str, seconds: float, workers: int | None = None) -> tuple[float, int, float]:
    """Wall time of the scan loop alone for ``seconds`` after its first ``START_UP_SECONDS`` (as the commands are
    measured), the points it made, and its CPU time (every thread's)."""
    config = load_preset(preset)
    scene = open_scene("urban")
    scanner = LidarScanner(config, EmbreeCaster(scene.mesh), scene.vehicle_pose, seed=0, workers=workers)
    for _ in scanner.frames(START_UP_SECONDS):
        pass
    points = 0
    start, cpu = time.perf_counter(), time.process_time()
    for frame in scanner.frames(seconds):
        points += len(frame)
    return time.perf_counter() - start, points, time.process_time() - cpu


def command_seconds(preset: str, seconds: float, output: str, folder: Path) -> tuple[float, float]:
    """Wall and CPU time of ``livox-viz scan --seconds S`` writing ``output``, in a child process."""
    target = ["--rosbag", str(folder / "bag")] if output == "rosbag" else ["--out", str(folder / f"cloud{output}")]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "livox_viz", "scan", "--preset", preset, "--seconds", f"{seconds:g}",
                    *target], check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    for leftover in folder.iterdir():
        subprocess.run(["rm", "-rf", str(leftover)], check=True)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def speed(preset: str, seconds: float, rounds: int) -> None:
    ratios: dict[str, list[float]] = {output: [] for output in OUTPUTS}
    loops: list[float] = []
    loop_cpu: list[float] = []
    writing: dict[str, list[float]] = {output: [] for output in OUTPUTS}
    cpu: dict[str, list[float]] = {output: [] for output in OUTPUTS}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for output in OUTPUTS:  # numba's caches and the page cache warmed for every output
            command_seconds(preset, START_UP_SECONDS, output, folder)
        for _ in range(rounds):
            loop, points, used = loop_seconds(preset, seconds - START_UP_SECONDS)
            loops.append(loop)
            loop_cpu.append(used)
            for output in OUTPUTS:
                whole, whole_cpu = command_seconds(preset, seconds, output, folder)
                start_up, start_up_cpu = command_seconds(preset, START_UP_SECONDS, output, folder)
                writing[output].append(whole - start_up)
                cpu[output].append(whole_cpu - start_up_cpu)
                ratios[output].append(loop / max(whole - start_up, 1e-9))
    print(f"{preset}, {seconds:g} s of scan ({points:,} points), {rounds} rounds; scan loop alone "
          f"{min(loops):.2f} s best ({(seconds - START_UP_SECONDS) / min(loops):.0f} x real time), CPU "
          f"{min(loop_cpu):.2f} s")
    for output in OUTPUTS:
        print(f"  scan -> {output:7s} start-up excluded: {min(writing[output]):6.2f} s best; "
              f"{statistics.median(ratios[output]):.2f} x the loop's speed (median of rounds; target >= 0.5), "
              f"{min(loops) / min(writing[output]):.2f} x best against best; CPU {min(cpu[output]):.2f} s "
              f"({min(cpu[output]) / min(loop_cpu):.2f} x the loop's: writing keeps up on 2 cores while about <= 2)")


def workers(preset: str, seconds: float, rounds: int) -> None:
    times = {count: [] for count in (1, 2)}
    for _ in range(rounds):
        for count in times:
            times[count].append(loop_seconds(preset, seconds, count)[0])
    one, two = min(times[1]), min(times[2])
    print(f"scan loop, {preset}, {seconds:g} s: 1 worker {seconds / one:.0f} x real time, 2 workers "
          f"{seconds / two:.0f} x ({one / two:.2f} x the speed of one)")


def memory(preset: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print(f"peak RSS of scan, {preset}, each child's own VmHWM (target: flat from 60 s to 600 s)")
        for output in OUTPUTS:
            peaks = []
            for seconds in (60, 600):
                target = ["--rosbag", str(folder / "bag")] if output == "rosbag" else [
                    "--out", str(folder / f"cloud{output}")]
                peak, wall = command_peak_mib(["scan", "--preset", preset, "--seconds", str(seconds), *target])
                peaks.append((peak, wall))
                for leftover in folder.iterdir():
                    subprocess.run(["rm", "-rf", str(leftover)], check=True)
            print(f"  {output:7s} 60 s: {peaks[0][0]:.0f} MiB ({peaks[0][1]:.0f} s); 600 s: {peaks[1][0]:.0f} MiB "
                  f"({peaks[1][1]:.0f} s)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--preset", default="livox_mid70")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=60.0)
    parser.add_argument("--long", action="store_true", help="also the 600 s memory runs (minutes)")
    args = parser.parse_args()
    print(f"{points_before(args.seconds, load_preset(args.preset).point_rate):,} rays")
    workers(args.preset, 10.0, args.rounds)
    speed(args.preset, args.seconds, args.rounds)
    if args.long:
        memory(args.preset)


if __name__ == "__main__":
    main()
