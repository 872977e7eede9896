"""Ray-casting throughput and end-to-end scan speed (issue: scene ray casting).

1 million pattern rays against the dense_terrain scene (>= 300 000 triangles):
ours (EmbreeCaster, 2 threads, float64-exact ranges) against a bare embreex
``EmbreeScene.run(..., query="DISTANCE")`` split over 2 threads and as one
single call, trimesh's ``intersects_location`` (on a subset, as rays/s) and
Open3D's ``RaycastingScene.cast_rays`` when open3d is installed. Then the whole
pipeline (pattern + cast + encode + decode) on the default scene, as a
multiple of real time.
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import best_of

from livox_viz import ScanPattern, load_preset
from livox_viz.directions import directions_from_xy
from livox_viz.poses import sensor_world_pose
from livox_viz.raycast import EmbreeCaster
from livox_viz.scan import LidarScanner
from livox_viz.scene import open_scene

RAYS = 1_000_000


def main() -> None:
    cfg = load_preset("livox_mid70")
    scene = open_scene("dense_terrain")
    pose = sensor_world_pose(cfg, scene.vehicle_pose)
    directions = directions_from_xy(ScanPattern(cfg, seed=0).take(RAYS).xy_deg) @ pose.rotation.T
    origin = pose.origin
    print(f"{RAYS:,} pattern rays, scene dense_terrain: {len(scene.mesh.faces):,} triangles")

    ours = EmbreeCaster(scene.mesh, threads=2)
    ours_s = best_of(lambda: ours.distances(origin, directions, cfg.range_max), 7)
    fast = EmbreeCaster(scene.mesh, threads=2, exact=False)
    fast_s = best_of(lambda: fast.distances(origin, directions, cfg.range_max), 7)

    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    bare = rtcore_scene.EmbreeScene()
    shift = ours.local_origin
    TriangleMesh(bare, (scene.mesh.vertices - shift).astype(np.float32), scene.mesh.faces.astype(np.int32))
    o32 = np.ascontiguousarray(np.broadcast_to(origin - shift, directions.shape), dtype=np.float32)
    d32 = np.ascontiguousarray(directions, dtype=np.float32)
    bare.run(o32[:10], d32[:10], query="DISTANCE")
    halves = [(o32[:RAYS // 2], d32[:RAYS // 2]), (o32[RAYS // 2:], d32[RAYS // 2:])]
    pool = ThreadPoolExecutor(2)

    def bare_two_threads() -> None:
        list(pool.map(lambda part: bare.run(part[0], part[1], query="DISTANCE"), halves))

    bare2_s = best_of(bare_two_threads, 7)
    bare1_s = best_of(lambda: bare.run(o32, d32, query="DISTANCE"), 3)
    check = ours.distances(origin, directions, cfg.range_max)
    reference = bare.run(o32, d32, query="DISTANCE").astype(np.float64)
    hit = np.isfinite(check)
    agree = np.abs(check[hit] - reference[hit]).max() if hit.any() else 0.0

    print(f"  ours (2 threads, float64 ranges): {ours_s * 1e3:8.1f} ms  {RAYS / ours_s / 1e6:6.2f} M rays/s")
    print(f"  ours, exact=False (float32):      {fast_s * 1e3:8.1f} ms  {RAYS / fast_s / 1e6:6.2f} M rays/s")
    print(f"  bare embreex run, 2 threads:      {bare2_s * 1e3:8.1f} ms  -> ours = {bare2_s / ours_s:5.2f} x its speed,"
          f" exact=False {bare2_s / fast_s:5.2f} x (target >= 0.9)")
    print(f"  bare embreex run, single call:    {bare1_s * 1e3:8.1f} ms  -> ours = {bare1_s / ours_s:5.2f} x its speed")
    print(f"  ours vs embreex float32 ranges: max difference {agree * 1e3:.3f} mm on {hit.sum():,} hits")

    subset = 200
    import trimesh

    intersector = trimesh.ray.ray_triangle.RayMeshIntersector(scene.mesh)
    origins_subset = np.broadcast_to(origin, (subset, 3))
    start = time.perf_counter()
    intersector.intersects_location(origins_subset, directions[:subset], multiple_hits=False)
    trimesh_rate = subset / (time.perf_counter() - start)
    print(f"  trimesh intersects_location:      {trimesh_rate / 1e3:8.1f} k rays/s (on {subset:,} rays) "
          f"-> ours = {RAYS / ours_s / trimesh_rate:7.0f} x its speed (target >= 4)")

    try:
        import open3d as o3d
    except ImportError:
        print("  open3d: not installed (pip install -e '.[bench]' to compare)")
    else:
        o3d_scene = o3d.t.geometry.RaycastingScene()
        o3d_scene.add_triangles(o3d.core.Tensor(scene.mesh.vertices.astype(np.float32)),
                                o3d.core.Tensor(scene.mesh.faces.astype(np.uint32)))
        rays = o3d.core.Tensor(np.hstack([np.broadcast_to(origin, directions.shape), directions]).astype(np.float32))
        o3d_s = best_of(lambda: o3d_scene.cast_rays(rays, nthreads=2), 3)
        print(f"  open3d cast_rays, 2 threads:      {o3d_s * 1e3:8.1f} ms  -> ours = {o3d_s / ours_s:5.2f} x its speed"
              " (target >= 1)")

    urban = open_scene("urban")
    seconds = 10.0

    def end_to_end() -> None:
        scanner = LidarScanner(cfg, urban.mesh, urban.vehicle_pose, seed=0)
        for _ in scanner.frames(seconds):
            pass

    e2e = best_of(end_to_end, 3)
    print(f"end to end (pattern + cast + int16 encode + decode), default preset and scene, {seconds:g} s of scan: "
          f"{e2e * 1e3:.0f} ms = {seconds / e2e:.0f} x real time (target >= 20)")


if __name__ == "__main__":
    main()
