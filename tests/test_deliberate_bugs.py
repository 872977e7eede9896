"""Tests for the deliberate bugs of issue 16 that the whole suite once let through.

Each test names the bug it catches, and checks against something the code
under test did not compute: an independent rotation (scipy), a geometric
truth (a wall, a triangle's plane), a third-party file reader, an injected
clock, or a reader in another process.
"""

from __future__ import annotations

import json
import re
import struct
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from livox_viz import load_preset
from livox_viz.casting.codec import max_decode_error
from livox_viz.casting.scan import LidarScanner
from livox_viz.core.poses import Pose
from livox_viz.files.export import PointCloudWriter
from livox_viz.scene.raycast import EmbreeCaster
from livox_viz.scene.scenes import open_scene
from livox_viz.wire.received import ReceivedFrame
from livox_viz.wire.rflysim import (
    LivoxFrame,
    Reassembler,
    SharedMemoryLink,
    WireFormat,
    pack_payload,
    split_datagrams,
    unpack_payload,
)
from livox_viz.wire.transport import publish

from .conftest import small_config


# Ray casting: the grazing-hit fallback --------------------------------------------------------
def _tilted_triangle(centre: np.ndarray) -> tuple[trimesh.Trimesh, np.ndarray, np.ndarray, np.ndarray]:
    """One large triangle on a tilted plane through ``centre``; returns it, its unit normal and two in-plane axes."""
    normal = np.array([0.3, -0.5, 0.8])
    normal /= np.linalg.norm(normal)
    u = np.cross(normal, [0.0, 0.0, 1.0])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    vertices = np.array([centre + 50.0 * u, centre - 25.0 * u + 43.0 * v, centre - 25.0 * u - 43.0 * v])
    return trimesh.Trimesh(vertices, [[0, 1, 2]], process=False), normal, u, v


def test_grazing_hits_keep_the_local_origin_offset() -> None:
    """Bug: the float32 fallback for a grazing hit casts from the world origin, not the scene's local one.

    Rays start within a few micrometres of a tilted triangle 3.6 km from the
    world origin and skim it. For some, float64 puts the origin behind the
    plane (a negative plane distance) while Embree's float32 copy of the scene
    still reports a hit: those take the fallback. Their distance must be that
    tiny skim, not a miss or a hit from somewhere else.
    """
    centre = np.array([3000.0, -2000.0, -150.0])
    mesh, normal, u, v = _tilted_triangle(centre)
    rng = np.random.default_rng(7)
    count = 40_000
    origins = (centre + rng.uniform(-10, 10, (count, 1)) * u + rng.uniform(-10, 10, (count, 1)) * v
               + rng.uniform(-3e-6, 3e-6, (count, 1)) * normal)
    angle = rng.uniform(0, 2 * np.pi, (count, 1))
    directions = np.cos(angle) * u + np.sin(angle) * v + rng.uniform(3e-4, 1e-3, (count, 1)) * normal
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    # The plane distance in float64, computed here from the vertices (not from the caster's planes).
    vertices = np.asarray(mesh.vertices)
    true_normal = np.cross(vertices[1] - vertices[0], vertices[2] - vertices[0])
    true_normal /= np.linalg.norm(true_normal)
    plane_distance = (vertices[0] - origins) @ true_normal / (directions @ true_normal)
    caster = EmbreeCaster(mesh, threads=1, exact=True)
    hit = caster.triangle_ids(origins, directions) >= 0
    grazing = np.flatnonzero(hit & (plane_distance < 0))
    assert grazing.size >= 20, "the geometry no longer makes grazing hits: the fallback is not exercised"
    skim = caster.distances(origins[grazing], directions[grazing])
    # float32 coordinates 10 m from the scene's centre are good to about 1e-6 m: over a slope of at
    # least 3e-4 the skim is a few millimetres at most. A wrong origin gives a miss or a far hit.
    assert np.all(np.isfinite(skim)) and skim.min() >= 0.0 and skim.max() < 0.02, skim
    hit_points = origins[grazing] + skim[:, None] * directions[grazing]
    assert np.abs((hit_points - vertices[0]) @ true_normal).max() < 1e-4
    # One origin for all rays takes the other branch of the fallback.
    for row in grazing[:5]:
        alone = caster.distances(origins[row], directions[row][None])
        assert np.isfinite(alone[0]) and 0.0 <= alone[0] < 0.02
    # The default float32 path casts the same rays from the same local origin: the same answer.
    np.testing.assert_array_equal(skim, EmbreeCaster(mesh, threads=1).distances(origins[grazing],
                                                                                directions[grazing]))


# UDP reassembly -------------------------------------------------------------------------------
def _one_chunk_datagram() -> bytes:
    points = np.arange(30, dtype=np.int16).reshape(10, 3)
    return split_datagrams(pack_payload(np.zeros(6), points), 0.5)[0]


@pytest.mark.parametrize("extra", [1, 6, 600])
def test_a_datagram_longer_than_its_length_field_is_dropped(extra: int) -> None:
    """Bug: the reassembler accepts a datagram whose length field is smaller than the datagram."""
    datagram = _one_chunk_datagram()
    assembler = Reassembler()
    assert assembler.feed(datagram + bytes(range(extra % 256)) + bytes(extra - extra % 256)) is None
    assert sum(assembler.drops.values()) == 1 and any("length" in reason for reason in assembler.drops)
    assert assembler.feed(datagram) is not None  # the honest datagram still makes its frame


def test_a_middle_chunk_with_trailing_bytes_costs_its_frame() -> None:
    """A longer chunk inside a three-chunk frame must not shift the points that follow it."""
    payload = pack_payload(np.zeros(6), np.arange(75_000, dtype=np.int16).reshape(-1, 3))
    datagrams = split_datagrams(payload, 1.0)
    assert len(datagrams) == 3
    assembler = Reassembler()
    results = [assembler.feed(d) for d in (datagrams[0], datagrams[1] + b"\x00\x00", datagrams[2])]
    assert results == [None, None, None]
    assert any("length" in reason for reason in assembler.drops)


# publish: pacing ------------------------------------------------------------------------------
class _FakeClock:
    """A wall clock that moves only when someone sleeps, or when the sender takes time."""

    def __init__(self, start: float = 1000.0) -> None:
        self.now = start
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds > 0
        self.sleeps.append(seconds)
        self.now += seconds


class _RecordingSender:
    def __init__(self, clock: _FakeClock, cost: float) -> None:
        self.clock = clock
        self.cost = cost
        self.sent_at: list[float] = []
        self.errors = 0
        self.wire = WireFormat()

    def send(self, timestamp: float, pos_ang: np.ndarray, xyz_int16: np.ndarray, frame_id: int = 0) -> int:
        self.sent_at.append(self.clock.now)
        self.clock.now += self.cost
        return 1


@pytest.mark.parametrize("speed", [0.5, 2.0, 4.0])
def test_publish_sends_frame_k_at_its_scan_time_over_the_speed(speed: float) -> None:
    """Bug: frames paced at t_k * speed instead of t_k / speed (no test timed publish)."""
    frames = list(LidarScanner(small_config(), open_scene("open_field").mesh, seed=0).frames(1.0))
    assert len(frames) == 10
    clock = _FakeClock()
    sender = _RecordingSender(clock, cost=0.001)
    report = publish(frames, sender, speed, clock=clock, sleep=clock.sleep)
    expected = np.array([f.timestamp for f in frames]) / speed
    np.testing.assert_allclose(np.array(sender.sent_at) - 1000.0, expected, atol=1e-9)
    assert report.frames == 10 and report.datagrams == 10
    # The run lasts until its last frame's end is due: its speed is what was asked (it said 1.1 x at 1 x).
    assert report.wall_seconds == pytest.approx(frames[-1].end_time / speed)
    assert report.scan_seconds / report.wall_seconds == pytest.approx(speed)


def test_publish_does_not_drift_and_never_waits_when_late() -> None:
    """Each frame is due at start + t_k / speed: a slow send delays only itself, sleeps do not pile up."""
    frames = list(LidarScanner(small_config(), open_scene("open_field").mesh, seed=0).frames(1.0))
    # At 2x a frame is due every 0.05 s: a send of 0.03 s is absorbed by the next sleep.
    clock = _FakeClock()
    publish(frames, _RecordingSender(clock, cost=0.03), 2.0, clock=clock, sleep=clock.sleep)
    np.testing.assert_allclose(np.array(clock.sleeps), [0.02] * 10, atol=1e-9)  # the last until its end
    # A send of 0.08 s is always late: frames go back to back and nothing sleeps.
    clock = _FakeClock()
    sender = _RecordingSender(clock, cost=0.08)
    publish(frames, sender, 2.0, clock=clock, sleep=clock.sleep)
    np.testing.assert_allclose(np.array(sender.sent_at) - 1000.0, 0.08 * np.arange(10), atol=1e-9)
    assert clock.sleeps == []
    unpaced_clock = _FakeClock()
    publish(frames, _RecordingSender(unpaced_clock, cost=0.0), None, clock=unpaced_clock, sleep=unpaced_clock.sleep)
    assert unpaced_clock.sleeps == []


def test_frames_after_a_slow_first_one_leave_at_their_own_intervals_not_in_a_burst() -> None:
    """Issue 44: the clock started before the first frame was ready (its scan compiled its loops), and the frames
    late by then all left at once: the first five within 16 ms, then 10 Hz; RflySim's own v3 client, which keeps
    the latest frame, showed 7 of 10. Each frame now leaves at its own interval from the late one."""
    clock = _FakeClock()
    frames = list(LidarScanner(small_config(), open_scene("open_field").mesh, seed=0).frames(1.0))

    def slow_start():
        clock.now += 0.45  # the first frame's compile
        yield from frames

    sender = _RecordingSender(clock, cost=0.001)
    report = publish(slow_start(), sender, 1.0, clock=clock, sleep=clock.sleep)
    gaps = np.diff(sender.sent_at)
    np.testing.assert_allclose(gaps, np.diff([f.timestamp for f in frames]), atol=1e-9)  # 0.1 s each, no burst
    assert report.late_frames == 1 and report.late_seconds == pytest.approx(0.45 - frames[0].timestamp)
    # A machine that falls behind once: the frames after it keep their intervals, and the report says so.
    clock = _FakeClock()
    sender = _RecordingSender(clock, cost=0.001)

    def stall_at_five():
        for frame in frames:
            if frame.index == 5:
                clock.now += 0.3
            yield frame

    report = publish(stall_at_five(), sender, 1.0, clock=clock, sleep=clock.sleep)
    gaps = np.diff(sender.sent_at)
    assert gaps.min() > 0.09 and report.late_frames == 1


# Point-cloud files read by third-party readers ---------------------------------------------------
@pytest.fixture(scope="module")
def scanned_frames() -> list:
    config = load_preset("livox_mid70")
    scene = open_scene("urban")
    return list(LidarScanner(config, scene.mesh, scene.vehicle_pose, seed=2).frames(0.25))


#: The per-point fields of the Livox SDK after x, y, z, range, time and frame, in the order files carry them.
LIVOX_FIELDS = ("reflectivity", "tag", "return_number", "number_of_returns")


def _written(path: Path, frames: list, ascii_mode: bool) -> Path:
    """The frames written by :class:`PointCloudWriter` in the sensor frame to ``path``."""
    with PointCloudWriter(path, "sensor", ascii=ascii_mode) as writer:
        for frame in frames:
            writer.write(frame)
    return path


def _assert_points_times_frames(read, frames: list) -> None:
    """x, y, z (the decoded points), time and frame as read by the third-party reader, against the frames'."""
    xyz = np.column_stack([read["x"], read["y"], read["z"]])
    np.testing.assert_allclose(xyz, np.concatenate([f.xyz_decoded for f in frames]), atol=1e-4)
    np.testing.assert_allclose(read["time"], np.concatenate([f.t for f in frames]), atol=1e-9)
    assert read["frame"].tolist() == np.concatenate([np.full(len(f), f.index) for f in frames]).tolist()


def _assert_livox_fields(read, frames: list) -> None:
    """Each Livox field as read by the third-party reader, one byte per point, against the frames'."""
    for name in LIVOX_FIELDS:
        values = np.asarray(read[name])
        assert values.dtype == np.uint8, name
        assert values.tolist() == np.concatenate([getattr(f, name) for f in frames]).tolist(), name


@pytest.mark.parametrize("ascii_mode", [False, True])
def test_pcd_header_and_points_through_pypcd4(tmp_path: Path, scanned_frames: list, ascii_mode: bool) -> None:
    """Bug: a PCD header whose WIDTH is one short (our own reader only looks at POINTS)."""
    pypcd4 = pytest.importorskip("pypcd4")
    cloud = pypcd4.PointCloud.from_path(_written(tmp_path / "cloud.pcd", scanned_frames, ascii_mode))
    total = sum(len(f) for f in scanned_frames)
    meta = cloud.metadata
    # An unorganised cloud (PCD v0.7): WIDTH is the point count, HEIGHT 1, and WIDTH * HEIGHT = POINTS.
    assert (meta.width, meta.height, meta.points) == (total, 1, total)
    assert meta.fields == ("x", "y", "z", "range", "time", "frame", *LIVOX_FIELDS)
    data = cloud.pc_data
    _assert_points_times_frames(data, scanned_frames)
    decoded = np.concatenate([f.xyz_decoded for f in scanned_frames])
    np.testing.assert_allclose(data["range"], np.linalg.norm(decoded, axis=1), rtol=1e-6)  # of the points it holds
    _assert_livox_fields(data, scanned_frames)


@pytest.mark.parametrize("ascii_mode", [False, True])
def test_ply_header_and_properties_through_plyfile(tmp_path: Path, scanned_frames: list, ascii_mode: bool) -> None:
    """The PLY writer's header and every property, read by plyfile (trimesh's reader checks only x, y, z)."""
    plyfile = pytest.importorskip("plyfile")
    ply = plyfile.PlyData.read(str(_written(tmp_path / "cloud.ply", scanned_frames, ascii_mode)))
    vertex = ply["vertex"]
    assert vertex.count == sum(len(f) for f in scanned_frames)
    assert [p.name for p in vertex.properties] == ["x", "y", "z", "range", "time", "frame", *LIVOX_FIELDS]
    assert any("frame sensor" in comment for comment in ply.comments)
    _assert_points_times_frames(vertex, scanned_frames)
    _assert_livox_fields(vertex, scanned_frames)


# The GUI's charts after a FOV change ----------------------------------------------------------------
def _coverage(xy: np.ndarray, half_fov_deg: float) -> float:
    """Coverage as scan-model.md section 7 defines it, written here with a 2-D histogram.

    5 mrad cells with a corner on the boresight; of the cells whose centre lies
    inside the FOV circle, the share holding at least one point.
    """
    cell = np.degrees(0.005)
    per_side = int(np.ceil(half_fov_deg / cell))
    edges = np.arange(-per_side, per_side + 1) * cell
    occupied, _, _ = np.histogram2d(xy[:, 0], xy[:, 1], bins=[edges, edges])
    centres = (edges[:-1] + edges[1:]) / 2
    inside = np.hypot(*np.meshgrid(centres, centres, indexing="ij")) <= half_fov_deg
    return np.count_nonzero((occupied > 0) & inside) / np.count_nonzero(inside)


def test_density_and_coverage_grids_follow_the_fov() -> None:
    """Bug: the density and coverage grids are not rebuilt when the FOV changes (coverage 0.117, not 0.639)."""
    pytest.importorskip("pyvista")
    from livox_viz.widgets.session import Session

    session = Session(load_preset("livox_mid70"), open_scene("open_field"), seed=0)
    session.advance_to(0.2)
    assert session.set_param("camera_fov", 30.0)
    half = session.config.half_fov_deg
    assert half == pytest.approx(15.0)
    session.advance_to(0.5)
    ring = session.pattern_ring
    xy = ring.ordered(ring.positions)[:, :2].astype(np.float64)
    assert ring.count == 50_000 and np.hypot(*xy.T).max() <= half + 1e-4
    assert session.visible_coverage() == pytest.approx(_coverage(xy, half), abs=1e-3)
    assert session.visible_coverage() > 0.5
    # The density image spans the new FOV: each point counted in its cell of a +-15 degree grid (a
    # point on a cell edge may fall either side of it).
    density = session.density
    counts, _, _ = np.histogram2d(xy[:, 1], xy[:, 0], bins=density.side, range=[[-half, half], [-half, half]])
    assert density.counts.sum() == ring.count
    assert np.abs(density.counts - counts).sum() <= 1e-3 * ring.count


def test_the_window_draws_density_and_coverage_for_the_new_fov() -> None:
    """The same bug seen in the window: the density image and the heads-up coverage after the FOV slider."""
    pytest.importorskip("pyvista")
    from livox_viz.widgets.app import LivoxVizApp
    from livox_viz.widgets.session import Session

    session = Session(load_preset("livox_mid70"), open_scene("open_field"), seed=0)
    app = LivoxVizApp(session, off_screen=True, window_size=(320, 240), views="pattern")
    try:
        app.on_param("camera_fov", 30.0)
        session.advance_to(0.5)
        session.display.drawing = "density"
        app.refresh()
        bounds = app.pattern_view.density_actor.GetBounds()
        np.testing.assert_allclose(bounds[:4], [-15.0, 15.0, -15.0, 15.0], atol=1e-6)
        shown = re.search(r"coverage ([\d.]+) %", app.hud.state.GetText(2))
        assert shown is not None
        xy = session.pattern_ring.ordered(session.pattern_ring.positions)[:, :2].astype(np.float64)
        assert float(shown.group(1)) == pytest.approx(100 * _coverage(xy, 15.0), abs=0.1)
    finally:
        app.close()


# Received frames in the world -------------------------------------------------------------------
def test_a_received_frame_is_placed_with_its_own_rotation() -> None:
    """Bug: a received frame placed in the world with the inverse rotation (every test used a zero rotation)."""
    rng = np.random.default_rng(3)
    xyz_int16 = rng.integers(-3000, 3000, size=(500, 3)).astype(np.int16)
    pos_ang = np.array([12.0, -4.0, -30.0, 0.3, -0.4, 2.1])
    wire = unpack_payload(pack_payload(pos_ang, xyz_int16), 0.2)
    frame = ReceivedFrame(wire, range_max=600.0, frame_rate=10.0)
    # scipy's intrinsic Z-Y-X (yaw, then pitch, then roll) is the aerospace body-to-NED rotation.
    rotation = Rotation.from_euler("ZYX", wire.pos_ang[[5, 4, 3]])
    expected = wire.pos_ang[:3] + rotation.apply(xyz_int16 / 32767 * 600.0)
    np.testing.assert_allclose(frame.xyz_world, expected, atol=1e-9)
    # Plainly: a point dead ahead of a sensor yawed 90 degrees lies east of it.
    east = LivoxFrame(0.0, np.array([0.0, 0.0, 0.0, 0.0, 0.0, np.pi / 2]), np.array([[32767, 0, 0]], np.int16))
    np.testing.assert_allclose(ReceivedFrame(east, 100.0, 10.0).xyz_world, [[0.0, 100.0, 0.0]], atol=1e-9)


def test_received_frames_of_a_turned_sensor_lie_on_the_wall() -> None:
    """Scanned with a rolled, pitched and yawed pose, sent over the wire, placed in the world: on the wall."""
    config = load_preset("livox_mid70")
    wall = trimesh.creation.box((1.0, 600.0, 600.0), trimesh.transformations.translation_matrix((40.5, 0, 0)))
    pose = Pose((0.0, 3.0, -5.0), 0.4, 0.15, -0.35)
    step = max_decode_error(config.range_max)
    received = []
    for frame in LidarScanner(config, wall, pose, seed=0).frames(0.3):
        sent = unpack_payload(pack_payload(frame.sensor_pose.as_array(), frame.xyz_int16), frame.timestamp)
        received.append(ReceivedFrame(sent, config.range_max, config.data_check_freq))
    world = np.concatenate([r.xyz_world for r in received])
    assert world.shape[0] > 20_000
    # float32 posAng on the wire costs at most about 1e-7 rad * 60 m.
    assert np.abs(world[:, 0] - 40.0).max() <= np.sqrt(3) * step + 1e-4


# Shared memory with a concurrent reader ---------------------------------------------------------------
_READER = textwrap.dedent("""
    import json, sys, time
    import numpy as np
    from livox_viz.wire.rflysim import SharedMemoryLink

    path, size, frames = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    link = SharedMemoryLink(path, size)
    seen, torn = [], []
    last = time.monotonic()
    print("ready", flush=True)
    while len(seen) < frames and time.monotonic() - last < 3.0:  # gives up 3 s after the last frame
        frame = link.read()
        if frame is None:
            continue
        last = time.monotonic()
        k = int(round(frame.timestamp))
        seen.append(k)
        want = (k * 7) % 30000
        if (frame.xyz_int16.shape[0] != 1000 + 37 * k or not np.all(frame.xyz_int16 == want)
                or not np.all(frame.pos_ang == k)):
            torn.append(k)
    link.close()
    print(json.dumps({"seen": seen, "torn": torn}))
""")


def test_a_concurrent_shared_memory_reader_never_sees_a_torn_frame(tmp_path: Path) -> None:
    """Bug: the writer raises its "written" flag before the frame is in the block.

    A reader in another process polls the block as fast as it can; the writer
    waits for it to take each frame before writing the next (so the only race
    left is the one under test). Frame k holds 1000 + 37 k points all equal to
    7 k and pose values k: a frame read before the writer finished mixes two
    frames or repeats the last.
    """
    frames = 150
    capacity = 1000 + 37 * frames
    size = capacity * 6 + 37
    path = tmp_path / "RflySim3DImg_0"
    writer = SharedMemoryLink(path, size, create=True)
    reader = subprocess.Popen([sys.executable, "-c", _READER, str(path), str(size), str(frames)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert reader.stdout is not None and reader.stdout.readline().strip() == "ready"
        flag = np.memmap(path, dtype=np.uint8, mode="r", shape=(1,))
        for k in range(frames):
            deadline = time.monotonic() + 5.0
            # Written (2) or being read (3): the reader has not finished with the last frame yet.
            while flag[0] in (2, 3) and reader.poll() is None and time.monotonic() < deadline:
                pass
            points = np.full((1000 + 37 * k, 3), (k * 7) % 30000, dtype=np.int16)
            assert writer.write(float(k), np.full(6, float(k)), points)
        out, _ = reader.communicate(timeout=60)
    finally:
        if reader.poll() is None:
            reader.kill()
            reader.wait()
        writer.close()
    result = json.loads(out.strip().splitlines()[-1])
    assert result["torn"] == [], f"torn frames {result['torn'][:10]}"
    assert result["seen"] == list(range(frames))


class _WatchedBlock:
    """Stands in for the writer's mapped block: what a reader would find the moment the flag says "written"."""

    def __init__(self, block) -> None:
        self.block = block
        self.seen_when_flagged: list[bytes] = []

    def __getitem__(self, key):
        return self.block[key]

    def __setitem__(self, key, value) -> None:
        self.block[key] = value
        if key == 0 and value == 2:
            self.seen_when_flagged.append(bytes(self.block))


def test_the_written_flag_is_raised_after_the_whole_frame(tmp_path: Path) -> None:
    """The same bug, deterministically: the block as it is at the instant the flag becomes 2."""
    path = tmp_path / "RflySim3DImg_0"
    size = 3000 * 6 + 37
    writer = SharedMemoryLink(path, size, create=True)
    reader = SharedMemoryLink(path, size)
    assert hasattr(writer, "_map"), "SharedMemoryLink keeps its block elsewhere now: update this test"
    watched = writer._map = _WatchedBlock(writer._map)
    try:
        for k, count in enumerate((3000, 10, 1700)):
            points = np.full((count, 3), 11 * (k + 1), dtype=np.int16)
            assert writer.write(0.1 * k, np.full(6, float(k)), points)
            snapshot = watched.seen_when_flagged[-1]
            # What a reader decodes from that instant's bytes: the whole new frame.
            flag, stamp, *pose, number = struct.unpack_from("<Bd6fi", snapshot)
            assert (flag, stamp, pose, number) == (2, 0.1 * k, [float(k)] * 6, count)
            got = np.frombuffer(snapshot, dtype="<i2", count=3 * count, offset=37).reshape(count, 3)
            np.testing.assert_array_equal(got, points)
            assert np.array_equal(reader.read().xyz_int16, points)
        assert len(watched.seen_when_flagged) == 3
    finally:
        writer._map = watched.block
        writer.close()
        reader.close()
