"""The datasheet return model's costs (issue 17: the cloud a real Livox returns).

1. Speed: a datasheet scan (noise, detection, the beam footprint sampled where it
   can change the answer, dual returns, reflectivity, tags) against the ideal
   scan of the same preset in the same run, interleaved, best of each (target:
   >= 0.5 x its speed), on the default scene and on the dense terrain.
2. The cost of each part: the return model's own clock per step
   (``ReturnModel.stage_seconds``), in ms per second of scan, and how many pulses
   each footprint test sent on.
3. Memory over a 10-minute flight with the datasheet model written to a bag, in
   child processes: peak RSS of 60 s against 600 s (target: flat).

The same figures with numpy's BLAS on one thread are printed for reference
(``OPENBLAS_NUM_THREADS=1`` in a child): the Risley stream's small matrix
products are several times slower with BLAS's default threads on this shared
2-core machine, which slows both scans alike.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.scene.raycast import EmbreeCaster
from livox_viz.scene.scenes import open_scene

SECONDS = 2.0
RUNS = 9


def speed(preset: str, scene_name: str) -> dict:
    """Interleaved ideal and datasheet scans of ``SECONDS``: best wall time of each, the model's steps."""
    config = load_preset(preset)
    scene = open_scene(scene_name)
    caster = EmbreeCaster(scene.mesh)
    best = {"ideal": float("inf"), "datasheet": float("inf")}
    stages: dict[str, float] = {}
    counts: dict[str, int] = {}
    for run in range(RUNS + 1):
        for model in best:
            scanner = LidarScanner(config.with_returns_model(model), caster, scene.vehicle_pose, seed=run)
            returns = scanner.mounted.returns
            if returns is not None:  # the broad phase and edge tables are made once per scene: not timed
                _ = returns.edges, returns.proxy
            start = time.perf_counter()
            points = sum(len(frame) for frame in scanner.frames(SECONDS))
            elapsed = time.perf_counter() - start
            if run == 0:
                continue  # warm-up
            best[model] = min(best[model], elapsed)
            if returns is not None:
                for name, seconds in returns.stage_seconds.items():
                    stages[name] = min(stages.get(name, float("inf")), seconds)
                counts = dict(returns.last_counts, points_per_s=int(points / SECONDS))
    return {"best": best, "stages": stages, "counts": counts}


def report(preset: str, scene_name: str, figures: dict, note: str = "") -> None:
    ideal, datasheet = figures["best"]["ideal"], figures["best"]["datasheet"]
    print(f"{preset} in {scene_name}{note}: ideal {ideal / SECONDS * 1e3:.0f} ms per second of scan "
          f"({SECONDS / ideal:.0f} x real time), datasheet {datasheet / SECONDS * 1e3:.0f} ms "
          f"({SECONDS / datasheet:.0f} x real time): datasheet = {ideal / datasheet:.2f} x the ideal's speed "
          "(target >= 0.5)")
    total = sum(figures["stages"].values())
    parts = ", ".join(f"{name} {seconds / SECONDS * 1e3:.1f}" for name, seconds in figures["stages"].items())
    print(f"  the return model's steps, ms per second of scan (best run each): {parts}; together "
          f"{total / SECONDS * 1e3:.0f} ms; the rest of the scan (pattern, rays, int16, frames) "
          f"{(datasheet - total) / SECONDS * 1e3:.0f} ms")
    counts = figures["counts"]
    pulses = max(counts.get("pulses", 1), 1)
    print(f"  last frame: {pulses:,} pulses; footprint leaves its triangle {counts.get('leaves', 0)} "
          f"({100 * counts.get('leaves', 0) / pulses:.1f} %), named by the broad phase {counts.get('near', 0)} "
          f"({100 * counts.get('near', 0) / pulses:.1f} %), covered by the probes {counts.get('covered', 0)} "
          f"({100 * counts.get('covered', 0) / pulses:.1f} %); {counts.get('points_per_s', 0):,} points/s")


def memory() -> None:
    code = ("import resource, sys\nfrom livox_viz.cli import main\n"
            "assert main(sys.argv[1:]) == 0\n"
            "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n")
    with tempfile.TemporaryDirectory() as tmp:
        for seconds in (60, 600):
            start = time.perf_counter()
            result = subprocess.run([sys.executable, "-c", code, "scan", "--preset", "livox_mid70_risley",
                                     "--trajectory", "circle", "--seconds", str(seconds), "--rosbag",
                                     f"{tmp}/bag{seconds}"], check=True, capture_output=True, text=True)
            peak = int(result.stdout.strip().splitlines()[-1])
            size = sum(p.stat().st_size for p in Path(f"{tmp}/bag{seconds}").iterdir()) / 2**30
            print(f"  {seconds:3d} s circle flight, datasheet returns, to a bag ({size:.1f} GiB) in "
                  f"{time.perf_counter() - start:.0f} s: peak RSS {peak / 1024:.0f} MiB")
            subprocess.run(["rm", "-rf", f"{tmp}/bag{seconds}"], check=True)


def main() -> None:
    if "--child" in sys.argv:
        print(json.dumps(speed(sys.argv[2], sys.argv[3])))
        return
    for preset, scene_name in (("livox_mid70_risley", "urban"), ("livox_mid40_risley", "urban"),
                               ("livox_mid70_risley", "dense_terrain")):
        report(preset, scene_name, speed(preset, scene_name))
    single = subprocess.run([sys.executable, __file__, "--child", "livox_mid70_risley", "urban"], check=True,
                            capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    report("livox_mid70_risley", "urban", json.loads(single.stdout), " (numpy's BLAS on one thread)")
    print("memory over a flight with the datasheet model, written to a bag (child processes; target: flat):")
    memory()


if __name__ == "__main__":
    main()
