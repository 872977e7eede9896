"""The datasheet return model's costs (issue 17: the cloud a real Livox returns).

1. Speed: a datasheet scan (noise, detection, the beam footprint sampled where it
   can change the answer, dual returns, reflectivity, tags) against the ideal
   scan of the same preset in the same run (target: >= 0.5 x its speed), on the
   default scene and on the dense terrain, two ways: as ``scan``, ``publish`` and
   the exports run it (``LidarScanner.frames``: frames cast side by side, one a
   core), and frame by frame from one thread as the window's ticks are
   (``MountedCaster.cast``: each model uses both cores within the frame). Both
   interleaved, best of each.
2. The cost of each part: the return model's own clock per step
   (``ReturnModel.stage_seconds``), in ms per second of scan, on one thread (as
   each worker of ``scan`` casts its frames) and frame by frame, and how many
   pulses each footprint test sent on.
3. Memory over a 10-minute flight written to a bag, in child processes: peak
   RSS of 60 s against 600 s (target: flat), the ideal model's beside it.

The same figures with numpy's BLAS on one thread are printed for reference
(``OPENBLAS_NUM_THREADS=1`` in a child): the Risley stream's small matrix
products are several times slower with BLAS's default threads on this shared
2-core machine, which slows both scans alike.

``--terrain`` alone: the dense terrain's datasheet scan against its ideal scan with the broad phase's tiles tested
by their boxes only and by their cells' boxes too (issue 34, item 4: target >= 0.3 x), in turns, same run; then
how many pulses a perfect broad phase would still name (a footprint ray really meets another tile), and each step's
cost on one thread, with beside it a scan whose broad phase names only those pulses: the bound of any exact broad
phase; and the same bound as ``scan`` runs it. ``--terrain-perfect`` runs only the perfect broad phase's parts.
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

import numpy as np
from _common import command_peak_mib

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner, MountedCaster
from livox_viz.patterns.factory import make_pattern
from livox_viz.scene.raycast import EmbreeCaster
from livox_viz.scene.scenes import open_scene

SECONDS = 1.0
RUNS = 7


def speed(preset: str, scene_name: str) -> dict:
    """Ideal and datasheet casts of the same frames (pattern included), interleaved frame by frame.

    Each frame of ``SECONDS`` of scan is made and cast ``RUNS`` times by each model in turn; the fastest of
    each is kept (the shared machine's other work only ever adds time), and the frames' bests are summed.
    The return model's own steps are timed the same way.
    """
    config = load_preset(preset)
    scene = open_scene(scene_name)
    caster = EmbreeCaster(scene.mesh)
    models = ("ideal", "datasheet")
    mounted = {m: MountedCaster(config.with_returns_model(m), caster, scene.vehicle_pose, seed=1) for m in models}
    patterns = {m: make_pattern(config.with_returns_model(m), seed=1) for m in models}
    returns = mounted["datasheet"].returns
    _ = returns.edges, returns.proxy  # made once per scene: not timed
    per_frame = config.points_per_frame
    frames = round(SECONDS * config.data_check_freq)
    best = {m: np.full(frames, np.inf) for m in models}
    stage_best = {name: np.full(frames, np.inf) for name in returns.stage_seconds}
    points = 0
    for k in range(frames):
        mounted["datasheet"].cast(patterns["datasheet"].points(k * per_frame, per_frame))  # warm
        for _ in range(RUNS):
            for model in models:
                before = dict(returns.stage_seconds)
                start = time.perf_counter()
                frame = mounted[model].cast(patterns[model].points(k * per_frame, per_frame))
                elapsed = time.perf_counter() - start
                best[model][k] = min(best[model][k], elapsed)
                if model == "datasheet":
                    for name, seconds in returns.stage_seconds.items():
                        stage_best[name][k] = min(stage_best[name][k], seconds - before[name])
        points += len(frame)
    return {"scan": scan_speed(preset, scene_name), "best": {m: float(best[m].sum()) for m in models},
            "stages": {name: float(v.sum()) for name, v in stage_best.items()},
            "counts": dict(returns.last_counts, points_per_s=int(points / SECONDS))}


def scan_speed(preset: str, scene_name: str, seconds: float = 4.0, runs: int = 15) -> dict[str, float]:
    """Seconds per second of scan of both models' scans of ``seconds`` of scan as ``scan`` runs it (frames side by
    side): the best of ``runs`` interleaved, and the median of each pair of runs' ratio (ideal / datasheet)."""
    config = load_preset(preset)
    scene = open_scene(scene_name)
    caster = EmbreeCaster(scene.mesh)
    models = ("ideal", "datasheet")

    def run(model: str) -> float:
        start = time.perf_counter()
        for _ in LidarScanner(config.with_returns_model(model), caster, scene.vehicle_pose, seed=1).frames(seconds):
            pass
        return (time.perf_counter() - start) / seconds

    for model in models:
        run(model)  # the scene's tables, numba's kernels
    times = np.array([[run(model) for model in models] for _ in range(runs)])
    return {"ideal": float(times[:, 0].min()), "datasheet": float(times[:, 1].min()),
            "paired": float(np.median(times[:, 0] / times[:, 1]))}


def one_thread_parts(preset: str, scene_name: str, runs: int = 9, must_name: list[np.ndarray] | None = None) -> None:
    """Each step's cost on one thread (frames cast inline, as each worker of ``scan`` casts its frame), against
    the ideal scan's on one thread: ms per second of scan, best of ``runs`` interleaved.

    With ``must_name`` (per frame, what :func:`terrain_met` found), a third scan runs beside them with a perfect
    broad phase: what ours names is cut to those pulses, the others go on as if named by nothing. Its speed, with
    and without the broad phase's own time, bounds what any exact broad phase can reach.
    """
    from livox_viz.casting.beam import TileProxy
    from livox_viz.scene.raycast import casting_in_this_thread

    config = load_preset(preset)
    scene = open_scene(scene_name)
    caster = EmbreeCaster(scene.mesh)
    models = ("ideal", "datasheet") + (("perfect broad phase",) if must_name is not None else ())
    mounted = {m: MountedCaster(config.with_returns_model("ideal" if m == "ideal" else "datasheet"), caster,
                                scene.vehicle_pose, seed=1) for m in models}
    returns = mounted["datasheet"].returns
    frame, cut = [0], [False]  # the frame being cast; whether the broad phase is the perfect one (the models share
    real_near = TileProxy.near  # their caster's proxy)

    def perfect_near(self, *args, **kwargs):
        near = real_near(self, *args, **kwargs)
        return near & must_name[frame[0]] if cut[0] else near

    if must_name is not None:
        TileProxy.near = perfect_near
        perfect = mounted["perfect broad phase"].returns
        perfect_stages = dict.fromkeys(perfect.stage_seconds, np.inf)
    pattern = make_pattern(config, seed=1)
    per_frame = config.points_per_frame
    chunks = [pattern.points(k * per_frame, per_frame) for k in range(round(SECONDS * config.data_check_freq))]
    best = dict.fromkeys(mounted, np.inf)
    stages = dict.fromkeys(returns.stage_seconds, np.inf)
    try:
        with casting_in_this_thread():
            for model in models[1:]:
                cut[0] = model == "perfect broad phase"
                for frame[0], chunk in enumerate(chunks):
                    mounted[model].cast(chunk)
            for _ in range(runs):
                for model, caster_of_model in mounted.items():
                    cut[0] = model == "perfect broad phase"
                    model_returns = caster_of_model.returns
                    before = dict(model_returns.stage_seconds) if model != "ideal" else {}
                    start = time.perf_counter()
                    for frame[0], chunk in enumerate(chunks):
                        caster_of_model.cast(chunk)
                    best[model] = min(best[model], time.perf_counter() - start)
                    kept = stages if model == "datasheet" else perfect_stages if model != "ideal" else {}
                    for name in kept:
                        kept[name] = min(kept[name], model_returns.stage_seconds[name] - before[name])
            if must_name is not None:
                cut[0] = True
                named = 0
                for frame[0], chunk in enumerate(chunks):
                    mounted["perfect broad phase"].cast(chunk)
                    named += perfect.last_counts["named"]
    finally:
        TileProxy.near = real_near
    if must_name is not None:
        print(f"  the perfect broad phase named {named:,} pulses of {sum(m.size for m in must_name):,}")
        ideal_best, perfect_best = best["ideal"], best["perfect broad phase"]
        free = perfect_best - perfect_stages["broad phase"]
        print(f"{preset} in {scene_name} on one thread with a perfect broad phase (names only the pulses a "
              f"footprint ray truly meets another tile for): datasheet {perfect_best / SECONDS * 1e3:.1f}"
              f" ms per second of scan ({ideal_best / perfect_best:.2f} x the ideal's speed); "
              f"with the broad phase free as well {free / SECONDS * 1e3:.1f} ms ({ideal_best / free:.2f} x); ours "
              f"{best['datasheet'] / SECONDS * 1e3:.1f} ms ({best['ideal'] / best['datasheet']:.2f} x). Its steps: "
              + ", ".join(f"{name} {seconds / SECONDS * 1e3:.1f}" for name, seconds in perfect_stages.items()))
    rest = best["datasheet"] - sum(stages.values())
    print(f"{preset} in {scene_name} on one thread (each frame as a worker of scan casts it): ideal "
          f"{best['ideal'] / SECONDS * 1e3:.1f}, datasheet {best['datasheet'] / SECONDS * 1e3:.1f} ms per second of "
          f"scan ({best['ideal'] / best['datasheet']:.2f} x); its steps: "
          + ", ".join(f"{name} {seconds / SECONDS * 1e3:.1f}" for name, seconds in stages.items())
          + f", the rest of the scan (pattern, rays, int16, frames) {rest / SECONDS * 1e3:.1f}")


def report(preset: str, scene_name: str, figures: dict, note: str = "") -> None:
    scanned = figures["scan"]
    print(f"{preset} in {scene_name}{note}: as scan runs it (frames side by side): ideal "
          f"{scanned['ideal'] * 1e3:.0f} ms per second of scan, datasheet {scanned['datasheet'] * 1e3:.0f} ms "
          f"({1 / scanned['datasheet']:.0f} x real time): datasheet = {scanned['ideal'] / scanned['datasheet']:.2f} "
          f"x the ideal's speed (target >= 0.5; median of the 15 interleaved pairs' ratios {scanned['paired']:.2f})")
    ideal, datasheet = figures["best"]["ideal"], figures["best"]["datasheet"]
    print(f"  frame by frame (the window's ticks): ideal {ideal / SECONDS * 1e3:.0f} ms per second of scan "
          f"({SECONDS / ideal:.0f} x real time), datasheet {datasheet / SECONDS * 1e3:.0f} ms "
          f"({SECONDS / datasheet:.0f} x real time): datasheet = {ideal / datasheet:.2f} x the ideal's speed "
          "(target >= 0.5)")
    total = sum(figures["stages"].values())
    parts = ", ".join(f"{name} {seconds / SECONDS * 1e3:.1f}" for name, seconds in figures["stages"].items())
    print(f"  the return model's steps frame by frame, thread-ms per second of scan (best of each frame, summed "
          f"over the frame's parts, one a core): {parts}; together {total / SECONDS * 1e3:.0f} ms")
    counts = figures["counts"]
    pulses = max(counts.get("pulses", 1), 1)
    print(f"  last frame: {pulses:,} pulses; footprint leaves its triangle {counts.get('leaves', 0)} "
          f"({100 * counts.get('leaves', 0) / pulses:.1f} %), named by the broad phase {counts.get('named', 0)} "
          f"({100 * counts.get('named', 0) / pulses:.1f} %), of them probed (footprint on its triangle) "
          f"{counts.get('probed', 0)} ({100 * counts.get('probed', 0) / pulses:.1f} %), covered by the probes "
          f"{counts.get('covered', 0)} "
          f"({100 * counts.get('covered', 0) / pulses:.1f} %); {counts.get('points_per_s', 0):,} points/s")


def terrain_broad_phase(runs: int = 3) -> None:
    """Issue 34 item 4: the dense terrain's datasheet scan against its ideal scan with the broad phase's tiles tested
    by their boxes only (as before) and by their sub-boxes too (``TileProxy.tight``), in turns, same run; and how
    many pulses each names (target: datasheet >= 0.3 x the ideal's speed)."""
    from livox_viz.casting.beam import TileProxy

    figures: dict[bool, list] = {False: [], True: []}
    for _ in range(runs):
        for tight in (False, True):
            TileProxy.tight = tight
            figures[tight].append(scan_speed("livox_mid70_risley", "dense_terrain", runs=5))
    TileProxy.tight = True
    for tight in (False, True):
        ratio = max(f["ideal"] / f["datasheet"] for f in figures[tight])
        paired = float(np.median([f["paired"] for f in figures[tight]]))
        best = min(f["datasheet"] for f in figures[tight])
        TileProxy.tight = tight
        counts = speed_counts("livox_mid70_risley", "dense_terrain")
        print(f"dense_terrain, broad phase {'tight (sub-boxes)' if tight else 'boxes only'}: datasheet "
              f"{best * 1e3:.0f} ms per second of scan ({1 / best:.0f} x real time), {ratio:.2f} x the ideal's speed "
              f"(best pair), median paired ratio {paired:.2f}; of {counts['pulses']:,} pulses (one second of scan) "
              f"the broad phase names {counts['named']:,} ({100 * counts['named'] / counts['pulses']:.1f} %), "
              f"{counts['probed']:,} of them probed ({100 * counts['probed'] / counts['pulses']:.1f} %: their "
              f"footprint stays on its triangle), covered {counts['covered']:,}; footprint leaves "
              f"{counts['leaves']:,}")
    TileProxy.tight = True


def terrain_met(preset: str = "livox_mid70_risley", scene_name: str = "dense_terrain",
                seconds: float = SECONDS) -> list[np.ndarray]:
    """What a perfect broad phase would name on the terrain, against what ours names: over one second of scan,
    the pulses one of whose footprint rays (72 over the footprint's cone: 24 on each of three circles, the
    largest its half-angle) first meets, before the pulse's reach, a triangle of a tile other than its hit's own
    (by Embree). A lower bound of what any broad phase keeping the cloud exact must name; most of them are
    footprints running on into the next tile of the same ground, not cover. Returns, per frame, the ``(n,)`` bool
    mask of those pulses (:func:`one_thread_parts`' ``must_name``)."""
    import math

    from livox_viz.casting import returns as returns_module
    from livox_viz.scene.raycast import casting_in_this_thread

    config = load_preset(preset).with_returns_model("datasheet")
    scene = open_scene(scene_name)
    caster = EmbreeCaster(scene.mesh)
    mounted = MountedCaster(config, caster, scene.vehicle_pose, seed=1)
    seen = []
    covered = returns_module.ReturnModel._covered

    def kept(self, leaves, directions, origins, basis, reach, triangle, distance, *rest):
        answer = covered(self, leaves, directions, origins, basis, reach, triangle, distance, *rest)
        seen.append((answer[1].copy(), triangle.copy(), directions.copy(), origins.copy(), reach.copy()))
        return answer

    returns_module.ReturnModel._covered = kept
    pattern = make_pattern(config, seed=1)
    per_frame = config.points_per_frame
    try:
        with casting_in_this_thread():
            for k in range(round(seconds * config.data_check_freq)):
                mounted.cast(pattern.points(k * per_frame, per_frame))
    finally:
        returns_module.ReturnModel._covered = covered
    proxy, tan_half = mounted.returns.proxy, mounted.returns.footprint.tan_half_max
    angles = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)
    pulses = named = met = 0
    must_name = []
    for near, triangle, directions, origins, reach in seen:
        pulses += near.size
        named += int(near.sum())
        rows = np.flatnonzero(triangle >= 0)
        rows = rows[proxy.triangle_tile[triangle[rows]] >= 0]
        u = directions[rows]
        helper = np.where(np.abs(u[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
        a = np.cross(u, helper)
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b = np.cross(u, a)
        rays = [u + share * tan_half * (math.cos(angle) * a + math.sin(angle) * b)
                for share in (1.0 / 3.0, 2.0 / 3.0, 1.0) for angle in angles]
        cone = np.concatenate([ray / np.linalg.norm(ray, axis=1, keepdims=True) for ray in rays]).astype(np.float32)
        pulse = np.tile(rows, len(rays))
        with casting_in_this_thread():
            first = caster.triangle_ids(origins[0], cone, float(reach.max())).astype(np.int64)
            far = caster.distances(origins[0], cone, float(reach.max()))
        tile = np.where(first >= 0, proxy.triangle_tile[np.maximum(first, 0)], -1)
        other = (tile >= 0) & (tile != proxy.triangle_tile[triangle[pulse]]) & (far <= reach[pulse])
        met += np.unique(pulse[other]).size
        frame_mask = np.zeros(near.size, dtype=np.bool_)
        frame_mask[pulse[other]] = True
        must_name.append(frame_mask)
    print(f"{scene_name}, {seconds:g} s of scan ({pulses:,} pulses): the broad phase names {named:,} "
          f"({100 * named / pulses:.1f} %); a footprint ray truly meets another tile's triangle before the reach for "
          f"at least {met:,} ({100 * met / pulses:.1f} %): what any exact broad phase must name")
    return must_name


def terrain_perfect_speed(preset: str = "livox_mid70_risley", scene_name: str = "dense_terrain",
                          seconds: float = 4.0, runs: int = 9) -> None:
    """Item 4's figure as ``scan`` runs it (frames side by side, one a core) with a perfect broad phase beside
    ours: one that names only the pulses :func:`terrain_met` finds a footprint ray of truly meeting another tile
    (its own cost is still ours). Interleaved with the ideal scan and ours, same run; the best of ``runs`` each and
    the median of the runs' paired ratios."""
    import threading

    from livox_viz.casting.beam import TileProxy
    from livox_viz.casting.returns import ReturnModel

    must_name = np.concatenate(terrain_met(preset, scene_name, seconds))  # by the pulses' stream index
    config = load_preset(preset)
    scene = open_scene(scene_name)
    caster = EmbreeCaster(scene.mesh)
    part = threading.local()
    perfect = [False]
    real_run, real_near = ReturnModel._cast_run, TileProxy.near

    def run_part(self, start, xy_deg, *rest):
        part.rows = (start, xy_deg.shape[0])
        return real_run(self, start, xy_deg, *rest)

    def near(self, *args, **kwargs):
        found = real_near(self, *args, **kwargs)
        if perfect[0]:
            start, n = part.rows
            found &= must_name[start:start + n]
        return found

    def run(model: str) -> float:
        perfect[0] = model == "perfect"
        returns = "ideal" if model == "ideal" else "datasheet"
        start = time.perf_counter()
        for _ in LidarScanner(config.with_returns_model(returns), caster, scene.vehicle_pose, seed=1).frames(seconds):
            pass
        return (time.perf_counter() - start) / seconds

    models = ("ideal", "ours", "perfect")
    ReturnModel._cast_run, TileProxy.near = run_part, near
    try:
        for model in models:
            run(model)
        times = np.array([[run(model) for model in models] for _ in range(runs)])
    finally:
        ReturnModel._cast_run, TileProxy.near = real_run, real_near
    best = times.min(axis=0)
    for k, label in ((1, "ours"), (2, "a perfect broad phase")):
        print(f"{scene_name}, {seconds:g} s as scan casts it (frames side by side), {label}: datasheet "
              f"{best[k] * 1e3:.0f} ms per second of scan ({1 / best[k]:.0f} x real time), {best[0] / best[k]:.2f} x "
              f"the ideal's {best[0] * 1e3:.0f} ms (best of {runs}); median of the paired ratios "
              f"{float(np.median(times[:, 0] / times[:, k])):.2f}")


def speed_counts(preset: str, scene_name: str) -> dict[str, int]:
    """The footprint tests' counts summed over one second of scan's frames (datasheet model, frame by frame)."""
    config = load_preset(preset).with_returns_model("datasheet")
    scene = open_scene(scene_name)
    mounted = MountedCaster(config, EmbreeCaster(scene.mesh), scene.vehicle_pose, seed=1)
    pattern = make_pattern(config, seed=1)
    per_frame = config.points_per_frame
    total: dict[str, int] = {}
    for k in range(round(SECONDS * config.data_check_freq)):
        mounted.cast(pattern.points(k * per_frame, per_frame))
        for name, value in mounted.returns.last_counts.items():
            total[name] = total.get(name, 0) + value
    return total


def memory() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        for model in ("ideal", "datasheet"):
            for seconds in (60, 600):
                bag = f"{tmp}/bag{seconds}"
                peak, wall = command_peak_mib(["scan", "--preset", "livox_mid70_risley", "--returns", model,
                                               "--trajectory", "circle", "--seconds", str(seconds), "--rosbag", bag])
                size = sum(p.stat().st_size for p in Path(bag).iterdir()) / 2**30
                print(f"  {seconds:3d} s circle flight, {model} returns, to a bag ({size:.1f} GiB) in "
                      f"{wall:.0f} s: peak RSS {peak:.0f} MiB")
                subprocess.run(["rm", "-rf", bag], check=True)


def main() -> None:
    if "--memory" in sys.argv:
        memory()
        return
    if "--terrain-perfect" in sys.argv:
        terrain_perfect_speed()
        one_thread_parts("livox_mid70_risley", "dense_terrain", must_name=terrain_met())
        return
    if "--terrain" in sys.argv:
        terrain_broad_phase()
        must_name = terrain_met()
        one_thread_parts("livox_mid70_risley", "dense_terrain", must_name=must_name)
        return
    if "--child" in sys.argv:
        print(json.dumps(speed(sys.argv[2], sys.argv[3])))
        return
    one_thread_parts("livox_mid70_risley", "urban")
    for preset, scene_name in (("livox_mid70_risley", "urban"), ("livox_mid40_risley", "urban"),
                               ("livox_mid70_risley", "dense_terrain"), ("livox_avia", "urban"),
                               ("livox_mid360", "urban")):
        report(preset, scene_name, speed(preset, scene_name))
    single = subprocess.run([sys.executable, __file__, "--child", "livox_mid70_risley", "urban"], check=True,
                            capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    report("livox_mid70_risley", "urban", json.loads(single.stdout), " (numpy's BLAS on one thread)")
    print("memory over a circle flight written to a bag (child processes; target: flat):")
    memory()


if __name__ == "__main__":
    main()
