"""Ray casting, poses, scan frames and their export."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import laspy
import numpy as np
import pytest
import trimesh

from livox_viz import LivoxVizError, ScanPattern, SensorConfig
from livox_viz.casting.codec import max_decode_error
from livox_viz.casting.directions import directions_from_xy
from livox_viz.casting.scan import LidarScanner
from livox_viz.cli import main
from livox_viz.config.mount import sensor_world_pose
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import enu_from_ned, euler_matrix
from livox_viz.files.export import PointCloudWriter
from livox_viz.scene.raycast import EmbreeCaster, TrimeshCaster
from livox_viz.scene.scenes import default_scene, load_mesh_file, load_scene, open_scene
from tests.readers import read_pcd


def at_origin(cfg: SensorConfig, **changes: object) -> SensorConfig:
    """The configuration with the sensor at the body origin, unrotated."""
    return replace(cfg, sensor_pos_xyz=(0.0, 0.0, 0.0), sensor_ang_euler=(0.0, 0.0, 0.0), **changes)


def wall(distance: float) -> trimesh.Trimesh:
    """A wall facing the sensor, normal along x, at ``distance`` metres."""
    return trimesh.creation.box((0.5, 400, 400), trimesh.transformations.translation_matrix((distance + 0.25, 0, 0)))


@pytest.mark.parametrize("distance", [3.0, 47.5, 180.0])
def test_range_to_a_plane(mid70: SensorConfig, distance: float) -> None:
    cfg = at_origin(mid70)
    frame = LidarScanner(cfg, wall(distance)).next_frame()
    assert len(frame) == frame.ray_count == cfg.points_per_frame
    alpha = np.radians(np.hypot(frame.xy_deg[:, 0], frame.xy_deg[:, 1]))
    # The default float32 ranges are well inside the int16 step; exact ones are float64-exact.
    np.testing.assert_allclose(frame.range_m, distance / np.cos(alpha), rtol=0, atol=0.1 * cfg.range_step)
    exact = LidarScanner(cfg, EmbreeCaster(wall(distance), exact=True)).next_frame()
    np.testing.assert_allclose(exact.range_m, distance / np.cos(alpha), rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(frame.xyz_decoded, axis=1), frame.range_m,
                               atol=math.sqrt(3) * max_decode_error(cfg.range_max))
    np.testing.assert_allclose(frame.xyz_decoded[:, 0], distance, atol=max_decode_error(cfg.range_max))


def test_hits_on_a_sphere_lie_on_it(mid70: SensorConfig) -> None:
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=5.0)
    sphere.apply_translation((20, 1, -1))
    scanner = LidarScanner(at_origin(mid70), EmbreeCaster(sphere, exact=True))
    frame = scanner.next_frame()
    assert 0 < len(frame) < frame.ray_count
    radius = np.linalg.norm(frame.xyz_world - (20, 1, -1), axis=1)
    # Flat faces lie inside the sphere by at most their sagitta (about 4 mm here).
    assert radius.max() <= 5.0 + 1e-9 and radius.min() > 5.0 - 0.01
    # Each hit lies on the plane of the triangle it hit.
    faces = scanner.caster.triangle_ids(np.zeros(3), directions_from_xy(frame.xy_deg))
    normals = sphere.face_normals[faces]
    on_plane = np.einsum("ij,ij->i", normals, frame.xyz_world - sphere.triangles[faces, 0])
    assert np.abs(on_plane).max() < 1e-9


def test_embree_and_trimesh_agree_on_the_default_scene(mid70: SensorConfig) -> None:
    scene = open_scene("urban")
    pose = sensor_world_pose(mid70, scene.vehicle_pose)
    xy = ScanPattern(mid70, seed=0).take(40_000).xy_deg[::20]
    directions = directions_from_xy(xy) @ pose.rotation.T
    embree = EmbreeCaster(scene.mesh, exact=True).distances(pose.origin, directions, mid70.range_max)
    numpy_backend = TrimeshCaster(scene.mesh).distances(pose.origin, directions, mid70.range_max)
    hit = np.isfinite(embree)
    assert np.array_equal(hit, np.isfinite(numpy_backend))
    assert 0.3 < hit.mean() < 1.0
    assert np.abs(embree[hit] - numpy_backend[hit]).max() < 1e-4


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_threads_do_not_change_results(threads: int) -> None:
    mesh = default_scene()
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(20_000, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    origin = np.array([0.0, 0.0, -1.8])
    reference = EmbreeCaster(mesh, threads=1).distances(origin, directions)
    assert np.array_equal(EmbreeCaster(mesh, threads=threads).distances(origin, directions), reference)


def test_a_split_call_runs_every_part_once_in_order_on_the_caller_and_the_workers() -> None:
    import threading

    from livox_viz.scene.raycast import casting_in_this_thread

    caster = EmbreeCaster(trimesh.creation.box((2, 2, 2)), threads=2)
    inline = []
    threads_seen: set[int] = set()
    both_working = threading.Event()

    def part(bounds: tuple[int, int]) -> tuple[tuple[int, int], int]:
        # A part waits (up to 10 s) until a second thread has taken one: on a busy machine a worker can wake
        # later than the caller finishes a short part, and then the caller rightly takes them all.
        threads_seen.add(threading.get_ident())
        if len(threads_seen) >= 2:
            both_working.set()
        both_working.wait(timeout=10.0)
        inline.append(caster.map_parts(lambda b: b, 100_000, 2048) == [(0, 100_000)])  # no nested split
        return bounds, threading.get_ident()

    found = caster.map_parts(part, 1_000_000, 2048)
    assert [f[0] for f in found] == [(0, 500_000), (500_000, 1_000_000)]  # one part a thread, in order
    assert len({f[1] for f in found}) == 2 and threading.get_ident() in {f[1] for f in found}
    assert all(inline)
    # Many parts: the caller and the worker take them in turn, each once, results in order.
    many = [(k, k + 1) for k in range(40)]
    taken = caster._share(part, many)
    assert [t[0] for t in taken] == many and len({t[1] for t in taken}) == 2
    assert len(caster.map_parts(part, 4000, 2048)) == 1  # under twice the least part: one part, here
    with casting_in_this_thread():
        assert [f[1] for f in caster.map_parts(part, 1_000_000, 2048)] == [threading.get_ident()]

    def failing(bounds: tuple[int, int]) -> None:
        if bounds[0] > 0:
            raise ValueError("part failed")

    with pytest.raises(ValueError, match="part failed"):
        caster.map_parts(failing, 100_000, 2048)
    # The caster still casts after a failed call.
    # Embree's distance is float32: 1 m to within a float32 ulp of 1 (6e-8), not exactly 1.
    np.testing.assert_allclose(caster.distances(np.zeros(3), np.array([[1.0, 0, 0]])), [1.0], rtol=0,
                               atol=2 * float(np.spacing(np.float32(1.0))))


def test_far_scene_keeps_float64_precision() -> None:
    # The same wall, 100 km from the world origin: Embree's float32 must not show.
    offset = np.array([1e5, -2e5, 0.0])
    mesh = wall(30.0)
    mesh.apply_translation(offset)
    directions = directions_from_xy(np.array([[0.0, 0.0], [10.0, 5.0], [-20.0, 3.0]]))
    distance = EmbreeCaster(mesh, exact=True).distances(offset, directions)
    np.testing.assert_allclose(distance, 30.0 / directions[:, 0], atol=1e-9)
    # The default float32 ranges are re-centred on the scene: still far inside a millimetre.
    fast = EmbreeCaster(mesh).distances(offset, directions)
    np.testing.assert_allclose(fast, 30.0 / directions[:, 0], atol=1e-4)


def test_returns_beyond_range_are_dropped(mid70: SensorConfig) -> None:
    scene = open_scene("urban")
    near = LidarScanner(mid70, scene.mesh, scene.vehicle_pose, seed=1)
    ranges = np.concatenate([f.range_m for f in near.frames(0.5)])
    assert ranges.max() <= 600.0
    far_cfg = mid70.with_param("range_max", 1000.0)
    far = LidarScanner(far_cfg, scene.mesh, scene.vehicle_pose, seed=1)
    far_frames = list(far.frames(0.5))
    far_ranges = np.concatenate([f.range_m for f in far_frames])
    assert (far_ranges > 790).sum() > 100  # the ridge at 800 m appears only with the longer range
    assert far_ranges.size > ranges.size
    # Each frame says how many rays returned.
    assert all(len(f) < f.ray_count for f in far_frames)


def test_decoded_error_bound_per_axis(mid70: SensorConfig) -> None:
    scene = open_scene("urban")
    for frame in LidarScanner(mid70, scene.mesh, scene.vehicle_pose).frames(0.3):
        assert np.abs(frame.xyz_decoded - frame.xyz_sensor).max() <= max_decode_error(600.0) * (1 + 1e-12)


def test_pose_composition_by_hand() -> None:
    vehicle = Pose((10.0, 0.0, -5.0), 0.0, 0.0, math.pi / 2)
    mount = Pose((1.0, 0.0, -0.3), 0.0, math.pi / 2, 0.0)
    sensor = vehicle.compose(mount)
    np.testing.assert_allclose(sensor.origin, [10.0, 1.0, -5.3], atol=1e-12)
    # The sensor's boresight (its x) points up (-z in NED) after a pitch of +90 degrees.
    np.testing.assert_allclose(sensor.rotation @ [1, 0, 0], [0, 0, -1], atol=1e-12)
    # Yaw 90 degrees turns the body's forward to east.
    np.testing.assert_allclose(vehicle.rotation @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    # Roll 90 degrees turns the body's right (y) to down (z).
    np.testing.assert_allclose(euler_matrix(math.pi / 2, 0, 0) @ [0, 1, 0], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(Pose.parse("10,0,-5,0,0,1.5707963267948966").as_array(), vehicle.as_array())


@pytest.mark.parametrize("text", ["1,2,3", "a,b,c,d,e,f", "1,2,3,4,5,nan", ""])
def test_bad_pose_strings(text: str) -> None:
    with pytest.raises(LivoxVizError, match="pose"):
        Pose.parse(text)


def test_mount_yaw_turns_the_cloud(mid70: SensorConfig) -> None:
    room = trimesh.creation.box((40, 40, 40))  # a cube is the same after a quarter turn
    straight = LidarScanner(at_origin(mid70), room).next_frame()
    turned = LidarScanner(replace(at_origin(mid70), sensor_ang_euler=(0.0, 0.0, math.pi / 2)), room).next_frame()
    np.testing.assert_allclose(turned.range_m, straight.range_m, atol=1e-9)
    quarter = euler_matrix(0, 0, math.pi / 2)
    np.testing.assert_allclose(turned.xyz_world, straight.xyz_world @ quarter.T, atol=1e-9)
    # The sensor frame does not change: a client sees the same cloud.
    np.testing.assert_allclose(turned.xyz_sensor, straight.xyz_sensor, atol=1e-9)


def test_mesh_files_and_up_axis(tmp_path: Path) -> None:
    box = trimesh.creation.box((1, 2, 3))
    box.apply_translation((5, 0, 10))
    path = tmp_path / "box.obj"
    box.export(path)
    z_up = load_mesh_file(path, "z")
    np.testing.assert_allclose(z_up.bounds, [[4.5, -1, -11.5], [5.5, 1, -8.5]], atol=1e-9)
    y_up = load_mesh_file(path, "y")  # glTF: +z forward -> north, -x right -> east, +y up -> -down
    np.testing.assert_allclose(y_up.bounds, [[8.5, -5.5, -1], [11.5, -4.5, 1]], atol=1e-9)
    assert len(load_scene(str(path)).faces) == 12


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (None, "no such mesh file"),
        (b"this is not a mesh", "not a mesh|no triangles"),
        (b"ply\nformat ascii 1.0\nelement vertex 0\nelement face 0\nend_header\n", "no triangles|not a mesh"),
        (b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN or infinite"),
        # A face naming a vertex the file lacks: trimesh's IndexError, after what is allowed.
        (b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", r"bad\.obj: not a mesh .*; allowed: a well-formed OBJ.*IndexError"),
    ],
)
def test_bad_mesh_files(tmp_path: Path, content: bytes | None, message: str) -> None:
    suffix = ".ply" if content and content.startswith(b"ply") else ".obj"
    path = tmp_path / f"bad{suffix}"
    if content is not None:
        path.write_bytes(content)
    with pytest.raises(LivoxVizError, match=message):
        load_mesh_file(path)


@pytest.fixture
def frames(mid70: SensorConfig) -> list:
    scene = open_scene("urban")
    return list(LidarScanner(mid70, scene.mesh, scene.vehicle_pose, seed=2).frames(0.25))


def expected_points(frames: list, coordinates: str) -> np.ndarray:
    """What every point-cloud format holds: the decoded points, in the sensor or placed in the world."""
    return np.concatenate([f.xyz_decoded if coordinates == "sensor" else f.xyz_world_decoded for f in frames])


@pytest.mark.parametrize("ascii_mode", [False, True])
@pytest.mark.parametrize("coordinates", ["sensor", "world"])
def test_ply_round_trip(tmp_path: Path, frames: list, ascii_mode: bool, coordinates: str) -> None:
    path = tmp_path / "cloud.ply"
    with PointCloudWriter(path, coordinates, ascii=ascii_mode) as writer:
        for frame in frames:
            writer.write(frame)
    cloud = trimesh.load(path)
    np.testing.assert_allclose(cloud.vertices, expected_points(frames, coordinates), atol=1e-4)
    assert f"comment frame {coordinates}".encode() in path.read_bytes()[:300]


@pytest.mark.parametrize("ascii_mode", [False, True])
def test_pcd_round_trip(tmp_path: Path, frames: list, ascii_mode: bool) -> None:
    path = tmp_path / "cloud.pcd"
    with PointCloudWriter(path, "sensor", ascii=ascii_mode) as writer:
        for frame in frames:
            writer.write(frame)
    data = read_pcd(path)
    xyz = np.column_stack([data["x"], data["y"], data["z"]])
    np.testing.assert_allclose(xyz, expected_points(frames, "sensor"), atol=1e-4)
    np.testing.assert_allclose(data["time"], np.concatenate([f.t for f in frames]), atol=1e-9)
    assert data["frame"].tolist() == np.concatenate([np.full(len(f), f.index) for f in frames]).tolist()
    assert b"frame sensor" in path.read_bytes()[:200]


def test_las_round_trip(tmp_path: Path, frames: list) -> None:
    path = tmp_path / "cloud.las"
    with PointCloudWriter(path, "world") as writer:
        for frame in frames:
            writer.write(frame)
    las = laspy.read(path)
    assert las.header.version.minor == 4
    xyz = np.column_stack([las.x, las.y, las.z])
    np.testing.assert_allclose(xyz, enu_from_ned(expected_points(frames, "world")), atol=1e-4)  # z up
    np.testing.assert_allclose(las.gps_time, np.concatenate([f.t for f in frames]), atol=1e-9)
    record = next(v for v in las.header.vlrs if v.user_id == "livox-viz")
    assert json.loads(record.record_data)["frame"] == "world"


def test_npz_and_csv_round_trip(tmp_path: Path, frames: list) -> None:
    npz, csv = tmp_path / "cloud.npz", tmp_path / "cloud.csv"
    for path in (npz, csv):
        with PointCloudWriter(path) as writer:
            for frame in frames:
                writer.write(frame)
    data = np.load(npz)
    assert np.array_equal(data["xyz_int16"], np.concatenate([f.xyz_int16 for f in frames]))
    assert data["xyz_int16"].dtype == np.int16
    np.testing.assert_array_equal(data["xyz_sensor"], expected_points(frames, "sensor"))
    np.testing.assert_array_equal(data["xyz_world"], np.concatenate([f.xyz_world for f in frames]))  # exact
    assert "sensor FRD" in str(data["frame_of_reference"])
    table = np.loadtxt(csv, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, :3], expected_points(frames, "sensor"), atol=1e-5)


def test_failed_export_leaves_nothing(tmp_path: Path, frames: list) -> None:
    target = tmp_path / "keep.ply"
    target.write_bytes(b"the user's old file")
    with pytest.raises(RuntimeError), PointCloudWriter(target) as writer:
        writer.write(frames[0])
        raise RuntimeError("disk full")
    assert target.read_bytes() == b"the user's old file"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.ply"]


def test_scan_cli_matches_the_api(tmp_path: Path, mid70: SensorConfig, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "scan.npz"
    assert main(["scan", "--seconds", "0.2", "--seed", "3", "--out", str(out)]) == 0
    scene = open_scene("urban")
    api = list(LidarScanner(mid70, scene.mesh, scene.vehicle_pose, seed=3).frames(0.2))
    assert np.array_equal(np.load(out)["xyz_int16"], np.concatenate([f.xyz_int16 for f in api]))


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--scene", "nowhere.obj"], "neither a scene preset"),
        (["--pose", "1,2,x,0,0,0"], "does not parse"),
        (["--scene", "urban", "--seconds", "0"], "allowed: a finite number > 0"),
    ],
)
def test_scan_cli_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    out = tmp_path / "out.ply"
    assert main(["scan", *argv, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_scan_with_nothing_in_range_writes_an_empty_valid_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "empty.pcd"
    assert main(["scan", "--scene", "open_field", "--pose", "0,0,-5,0,1.5,0", "--seconds", "0.1",
                 "--out", str(out)]) == 0
    assert "warning: no ray hit anything" in capsys.readouterr().err
    assert read_pcd(out)["x"].size == 0


def test_float32_mode_agrees_within_a_millimetre() -> None:
    scene = open_scene("urban")
    rng = np.random.default_rng(3)
    directions = directions_from_xy(rng.uniform(-25, 25, size=(5000, 2)))
    origin = np.array([0.0, 0.0, -1.8])
    exact = EmbreeCaster(scene.mesh, exact=True).distances(origin, directions, 600.0)
    fast = EmbreeCaster(scene.mesh).distances(origin, directions, 600.0)
    assert np.array_equal(np.isfinite(exact), np.isfinite(fast))
    hit = np.isfinite(exact)
    assert np.abs(exact[hit] - fast[hit]).max() < 1e-3


def test_a_forked_child_scans_on_threads_of_its_own(mid70: SensorConfig) -> None:
    """frames() keeps its worker threads for the process; a child forked after a scan has none of them, and must
    not hand its frames to a pool whose threads are not there (it would wait for them for ever)."""
    import os

    from tests.forking import child_exit_code

    caster = EmbreeCaster(wall(20.0), threads=1)
    expected = sum(len(frame) for frame in LidarScanner(at_origin(mid70), caster).frames(0.25))
    assert expected > 0
    pid = os.fork()
    if pid == 0:  # the child: exit 0 when its scan gives the parent's points
        try:
            found = sum(len(frame) for frame in LidarScanner(at_origin(mid70), caster).frames(0.25))
            os._exit(0 if found == expected else 1)
        except BaseException:
            os._exit(2)
    assert child_exit_code(pid, 60.0, "its scan") == 0
