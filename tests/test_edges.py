"""Edges the mutation run (``make mutate``) found unguarded: each test here kills a mutant that survived.

The behaviour each checks is one a user relies on: a frame cast in parts is
the frame cast whole; the ends of a documented option range are inside it.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from livox_viz import load_preset
from livox_viz.casting import scan as scan_module
from livox_viz.casting.scan import LidarScanner
from livox_viz.cli import MODEL_COMMANDS, build_parser
from livox_viz.core.poses import Pose
from livox_viz.motion.trajectory import Trajectory
from livox_viz.patterns.factory import make_pattern
from livox_viz.scene.scenes import open_scene


# Casting in parts -----------------------------------------------------------------------------
def _turning_flight() -> Trajectory:
    t = np.arange(0.0, 0.5, 0.001)
    position = np.column_stack([6.0 * t, 0.5 * t, np.full_like(t, -2.0)])
    return Trajectory("turning", t, position, Rotation.from_rotvec(np.outer(0.8 * t, [0.2, 0.1, 1.0])).as_quat())


@pytest.mark.parametrize("moving", [False, True])
def test_a_frame_cast_in_parts_is_the_frame_cast_whole(monkeypatch: pytest.MonkeyPatch, moving: bool) -> None:
    """Frames longer than CAST_PART rays are cast part by part: every ray keeps its own time and pose."""
    config = load_preset("livox_mid70")
    scene = open_scene("urban")
    flight = _turning_flight() if moving else None
    pose = None if moving else Pose((0.0, 0.0, -2.0), 0.1, -0.05, 0.4)

    def cast(part: int):
        monkeypatch.setattr(scan_module, "CAST_PART", part)
        scanner = LidarScanner(config, scene.mesh, pose, seed=4, trajectory=flight)
        return scanner.cast(make_pattern(config, seed=4).take(10_000))

    whole, parts = cast(1 << 20), cast(999)  # ten full parts and a short one
    assert len(whole) > 5_000
    for name in ("stream_index", "t", "range_m", "xyz_sensor", "xyz_world", "xyz_int16"):
        np.testing.assert_array_equal(getattr(parts, name), getattr(whole, name), err_msg=name)
    if moving:
        np.testing.assert_array_equal(parts.point_origin, whole.point_origin)
        np.testing.assert_array_equal(parts.point_quaternion, whole.point_quaternion)


# Option ranges: the ends are allowed --------------------------------------------------------------
@pytest.fixture(scope="module")
def parser():
    return build_parser(MODEL_COMMANDS)


@pytest.mark.parametrize(("argv", "name", "value"), [
    (["publish", "--speed", "0.01"], "speed", 0.01),
    (["publish", "--speed", "1000"], "speed", 1000.0),
    (["fit", "mid40", "--model", "risley", "--beams", "1"], "beams", 1),
    (["fit", "mid40", "--model", "risley", "--beams", "16"], "beams", 16),
])
def test_the_ends_of_an_option_range_are_allowed(parser, argv: list[str], name: str, value: float) -> None:
    assert getattr(parser.parse_args(argv), name) == value


@pytest.mark.parametrize("argv", [
    ["publish", "--speed", "0.0099"], ["publish", "--speed", "1000.5"],
    ["fit", "mid40", "--model", "risley", "--beams", "0"], ["fit", "mid40", "--model", "risley", "--beams", "17"],
])
def test_just_past_the_ends_is_refused(parser, argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_status:
        parser.parse_args(argv)
    assert exit_status.value.code == 2 and "allowed" in capsys.readouterr().err


# fit --model risley from the command line ------------------------------------------------------------
def test_fit_risley_command_replays_the_preset_it_was_fitted_to(tmp_path, capsys: pytest.CaptureFixture[str]) -> None:
    """``fit --to PRESET --model risley --out`` writes a preset whose track is the preset's own."""
    from livox_viz import load_config
    from livox_viz.cli import main

    out = tmp_path / "fitted.json"
    assert main(["fit", "--to", "livox_mid70_risley", "--model", "risley", "--seconds", "0.5", "--beams", "1",
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "lasers           1 (forced; the rows' geometry says 1)" in printed
    fitted, source = load_config(out), load_preset("livox_mid70_risley")
    assert fitted.pattern_model == "risley" and fitted.risley.lasers == 1
    ours = make_pattern(fitted, seed=0).take(20_000).xy_deg
    theirs = make_pattern(source, seed=0).take(20_000).xy_deg
    assert np.abs(ours - theirs).max() < 1e-3


# Validation limits ---------------------------------------------------------------------------------------
def _risley(term: tuple[int, int] = (2, -1), **changes):
    from livox_viz.config.risley_params import RisleyParams

    return RisleyParams((50.0, -80.0), (0.0, 0.0), ((1, 0), (0, 1), term), np.array([[9.0, 9.5, 0.3 + 0.1j]]),
                        **changes)


def test_risley_term_orders_up_to_32_are_allowed_and_33_is_not() -> None:
    from livox_viz import ConfigError

    assert _risley((32, -32)).terms[-1] == (32, -32)
    for term in ((33, 0), (0, -33)):
        with pytest.raises(ConfigError, match=r"\|m\|, \|l\| <= 32"):
            _risley(term)


def test_risley_deflection_and_spacing_limits_are_inclusive() -> None:
    from livox_viz import ConfigError

    assert _risley(deflection_deg=(45.0, 45.0)).deflection_deg == (45.0, 45.0)
    assert _risley(laser_spacing=10.0).laser_spacing == 10.0 and _risley(laser_spacing=0.0).laser_spacing == 0.0
    for changes in ({"deflection_deg": (45.001, 9.0)}, {"deflection_deg": (9.0, 0.0)}, {"laser_spacing": 10.001},
                    {"laser_spacing": -0.001}):
        with pytest.raises(ConfigError, match="allowed"):
            _risley(**changes)


def test_fitted_coefficients_cannot_be_changed_in_place() -> None:
    """The params are frozen (and keyed for caches by their values): so are their coefficient arrays."""
    params = _risley()
    assert not params.base_coefficients.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        params.base_coefficients[0, 0] = 1.0


# Defaults -----------------------------------------------------------------------------------------------
def test_a_configuration_made_from_scratch_is_the_documents_seed() -> None:
    """SensorConfig() with no arguments is the seed configuration of the spec (tests/conftest.py holds its JSON)."""
    from livox_viz import SensorConfig

    from .conftest import SEED_JSON

    assert SensorConfig() == SensorConfig.from_json_dict(SEED_JSON)


# Files --------------------------------------------------------------------------------------------------
def test_las_points_claim_no_colour(tmp_path) -> None:
    """LAS 1.4 point format 6: no RGB channel a viewer would paint the cloud black from."""
    import laspy

    from livox_viz.files.export import PointCloudWriter

    config = load_preset("livox_mid70")
    scene = open_scene("urban")
    path = tmp_path / "cloud.las"
    with PointCloudWriter(path, "world") as writer:
        writer.write(LidarScanner(config, scene.mesh, scene.vehicle_pose, seed=1).next_frame())
    las = laspy.read(path)
    assert las.header.point_format.id == 6
    assert not {"red", "green", "blue"} & set(las.point_format.dimension_names)


def test_every_bag_message_is_canonical_cdr_and_clouds_declare_their_layout(tmp_path) -> None:
    """Each message's bytes are exactly what rosbags serialises (no byte too many or too few), and
    every PointCloud2 field lies inside the point, apart from the others, where it says."""
    pytest.importorskip("rosbags")
    from rosbags.rosbag2 import Reader

    from livox_viz.cli import main

    from .test_rosbag import typestore

    bag, npz = tmp_path / "bag", tmp_path / "cloud.npz"
    assert main(["scan", "--seconds", "0.3", "--trajectory", "line", "--trajectory-speed", "6", "--rosbag", str(bag),
                 "--out", str(npz)]) == 0
    store = typestore()
    sizes = {1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 8: 8}  # PointField datatypes
    seen: dict[str, int] = {}
    clouds = []
    with Reader(bag) as reader:
        for connection, _, raw in reader.messages():
            message = store.deserialize_cdr(raw, connection.msgtype)
            assert bytes(store.serialize_cdr(message, connection.msgtype)) == bytes(raw), connection.topic
            seen[connection.topic] = seen.get(connection.topic, 0) + 1
            if connection.msgtype == "sensor_msgs/msg/PointCloud2":
                clouds.append(message)
    assert {"/livox/imu", "/odom", "/livox/points", "/livox/lidar"} <= set(seen) and seen["/livox/imu"] > 10
    data = np.load(npz)
    for index, cloud in enumerate(clouds):
        spans = sorted((f.offset, f.offset + sizes[f.datatype] * f.count) for f in cloud.fields)
        assert all(end <= start for (_, end), (start, _) in itertools.pairwise(spans))
        assert spans[-1][1] <= cloud.point_step and len(cloud.data) == cloud.point_step * cloud.width * cloud.height
        names = [f.name for f in cloud.fields]
        layout = np.dtype({"names": names, "offsets": [f.offset for f in cloud.fields], "itemsize": cloud.point_step,
                           "formats": [{7: "<f4", 8: "<f8", 2: "u1"}[f.datatype] for f in cloud.fields]})
        decoded = np.frombuffer(bytes(cloud.data), dtype=layout)
        mine = data["frame"] == index
        # Nanoseconds as float64, the Livox ROS driver 2's convention (256 ns resolution at this epoch).
        np.testing.assert_allclose((decoded["timestamp"] - 1.7e18) / 1e9, data["t"][mine], atol=1e-6)
        np.testing.assert_allclose(np.column_stack([decoded["x"], decoded["y"], decoded["z"]]),
                                   data["xyz_sensor"][mine] * [1, -1, -1], atol=1e-5)


# compare: its times and its picture --------------------------------------------------------------------
@pytest.fixture(scope="module")
def comparison():
    from livox_viz import ScanPattern
    from livox_viz.fitting.compare import compare
    from livox_viz.fitting.reference import ReferencePattern

    config = load_preset("livox_mid70")
    xy = ScanPattern(config.with_param("petal_height", 3.5), seed=1).take(400_000).xy_deg
    return compare(config, ReferencePattern("other", xy, np.arange(len(xy)) / 1e5, 1e5), seed=0)


def test_compare_integration_times_increase_and_coverage_grows(comparison) -> None:
    assert np.all(np.diff(comparison.seconds) > 0) and comparison.seconds[-1] == 4.0
    for curve in (comparison.coverage_ours, comparison.coverage_reference):
        assert np.all(np.diff(curve) >= 0) and 0 < curve[0] < curve[-1] <= 1


def test_the_comparison_picture_shows_what_its_labels_say(comparison, tmp_path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    """Each panel's curves are the numbers its axis names (the PNG itself is only looked at by people)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from livox_viz.fitting.plot import plot_comparison

    drawn = []
    close = plt.close
    monkeypatch.setattr(plt, "close", lambda figure=None: (drawn.append(figure), close(figure)))
    plot_comparison(comparison, tmp_path / "c.png", "a title")
    assert (tmp_path / "c.png").stat().st_size > 10_000 and len(drawn) == 1
    axes = np.array(drawn[0].axes).reshape(2, 2)
    c, centres = comparison, 0.5 * (comparison.density_edges_deg[1:] + comparison.density_edges_deg[:-1])
    panels = {
        (0, 0): [(c.seconds, 100 * c.coverage_reference), (c.seconds, 100 * c.coverage_ours)],
        (1, 0): [(c.seconds, 100 * (c.coverage_ours - c.coverage_reference))],
        (0, 1): [(centres, c.density_reference / 1e6), (centres, c.density_ours / 1e6)],
        (1, 1): [(centres, (c.density_ours - c.density_reference) / 1e6)],
    }
    for (row, column), curves in panels.items():
        lines = [line for line in axes[row, column].get_lines() if len(line.get_xdata()) > 2]
        assert len(lines) == len(curves), (row, column)
        for line, (x, y) in zip(lines, curves, strict=True):
            np.testing.assert_allclose(line.get_xdata(), x)
            np.testing.assert_allclose(line.get_ydata(), y)
    assert "coverage" in axes[0, 0].get_ylabel() and "density" in axes[0, 1].get_ylabel()
    assert axes[0, 0].get_xscale() == "log" and axes[0, 1].get_yscale() == "log"
    assert [t.get_text() for t in axes[0, 0].get_legend().get_texts()] == ["reference", "ours"]


# Built-in flights and trajectories -----------------------------------------------------------------------
@pytest.mark.parametrize("name", ["line", "circle", "figure8"])
def test_a_built_in_flight_looks_where_it_flies(name: str) -> None:
    """The vehicle's forward axis (body x, in the world) points along its horizontal velocity."""
    from livox_viz.core.rotations import quat_rotate
    from livox_viz.motion.flights import builtin_trajectory

    flight = builtin_trajectory(name, 6.0, Pose((3.0, -2.0, -5.0), 0.0, 0.0, 0.7), 12.0)
    velocity = np.gradient(flight.position, flight.t, axis=0)[5:-5, :2]
    forward = quat_rotate(flight.quaternion[5:-5], np.tile([1.0, 0.0, 0.0], (len(velocity), 1)))[:, :2]
    along = np.einsum("ij,ij->i", forward, velocity) / np.linalg.norm(velocity, axis=1)
    assert along.min() > 0.999


@pytest.mark.parametrize("name", ["line", "circle", "figure8"])
def test_a_built_in_flight_cruises_at_the_speed_asked(name: str) -> None:
    """Between its ramps (from rest and back to rest) a built-in flight flies at the speed asked, all along.

    The figure-8 once ran at a constant lemniscate parameter rate scaled by a guessed
    mean (1.22 a du/dt; it is 0.97 a du/dt): about 4.8 m/s when asked 6,
    faster at the crossing than in the loops.
    """
    from livox_viz.motion.flights import RAMP_SECONDS, builtin_trajectory

    flight = builtin_trajectory(name, 6.0, Pose((0.0, 0.0, -2.0)), 20.0)
    speed = np.linalg.norm(np.diff(flight.position, axis=0), axis=1) / np.diff(flight.t)
    cruising = (flight.t[1:] > RAMP_SECONDS + 0.1) & (flight.t[1:] < 20.0 - RAMP_SECONDS - 0.1)
    np.testing.assert_allclose(speed[cruising], 6.0, rtol=0.001)
    # The distance flown is the cruise plus the two ramps (each flown at half the speed on average).
    assert speed.sum() * 0.01 == pytest.approx(6.0 * (20.0 - RAMP_SECONDS), rel=0.001)


def test_the_figure8_is_flown_by_arc_length_along_bernoulli_lemniscate() -> None:
    """The lemniscate's parameter after s metres, checked against its arc length integrated independently from
    its points' derivatives (finite differences of figure8_point, not the analytic speed the code integrates);
    its heading is the direction of those differences."""
    from scipy.integrate import quad

    from livox_viz.motion.flights import figure8_parameter, figure8_point

    a = 16.0
    s = np.array([0.0, 3.7, 21.0, 48.5, 130.0])
    u = figure8_parameter(s, a)

    def speed(v: float, h: float = 1e-6) -> float:
        ahead, behind = figure8_point(np.array([v + h]), a), figure8_point(np.array([v - h]), a)
        return float(np.hypot(ahead[0] - behind[0], ahead[1] - behind[1])[0] / (2 * h))

    flown = [quad(speed, 0.0, end, limit=200)[0] for end in u]
    np.testing.assert_allclose(flown, s, rtol=1e-7, atol=1e-7)
    assert np.all(np.diff(u) > 0)
    v = np.linspace(0.0, 2 * np.pi, 2001)
    x, y, heading = figure8_point(v, a)
    np.testing.assert_allclose(np.cos(heading[1:-1]), np.gradient(x, v)[1:-1] / np.hypot(np.gradient(x, v),
                                                                                          np.gradient(y, v))[1:-1],
                               atol=1e-4)


# Reference tables and the pattern factory -------------------------------------------------------------------
@pytest.mark.parametrize("rate", [0.0, -5.0, float("nan"), float("inf")])
def test_a_table_rate_must_be_a_positive_number(tmp_path, rate: float) -> None:
    from livox_viz import LivoxVizError
    from livox_viz.fitting.reference import load_reference

    path = tmp_path / "table.npy"
    np.save(path, np.zeros((100, 2)))
    with pytest.raises(LivoxVizError, match="allowed: points per second > 0"):
        load_reference(path, rate=rate)
    assert len(load_reference(path, rate=1e-3).t) == 100


def test_the_pattern_seed_defaults_to_zero() -> None:
    """What ``scan``, ``publish`` and the window use without --seed: the same stream as seed 0."""
    config = load_preset("livox_mid70")
    np.testing.assert_array_equal(make_pattern(config).take(5_000).xy_deg,
                                  make_pattern(config, seed=0).take(5_000).xy_deg)
    assert not np.array_equal(make_pattern(config, seed=1).take(5_000).xy_deg,
                              make_pattern(config, seed=0).take(5_000).xy_deg)


def test_terrain_hills_rise_from_its_centre_by_up_to_the_amplitude(tmp_path) -> None:
    """A terrain object's surface lies between its centre height and ``amplitude`` metres above it (NED: -z)."""
    import json

    path = tmp_path / "hills.json"
    path.write_text(json.dumps({"objects": [{"type": "terrain", "center": [10, 0, 0], "size": [200, 200],
                                             "cells": 80, "amplitude": 4.0, "wavelength": 25.0}]}))
    vertices = np.asarray(open_scene(path).mesh.vertices)
    z = vertices[:, 2]
    assert z.max() <= 1e-9 and z.min() >= -4.0 - 1e-9
    assert z.max() - z.min() > 3.0
    # Hills about a wavelength apart: along 200 m the surface crosses its mean about 2 x 200 / 25 times.
    row = vertices[np.abs(vertices[:, 1]) < 1e-9]
    heights = row[np.argsort(row[:, 0]), 2]
    crossings = np.count_nonzero(np.diff(np.sign(heights - heights.mean())))
    assert 10 <= crossings <= 22


def test_risley_spectral_peaks_find_slow_and_fast_lines_between_bins() -> None:
    """The frequency search behind the Risley fit: two lines, one slow, both off the FFT grid, found to 1 mHz."""
    from livox_viz.fitting.track_fit import spectral_peaks

    rate = 10_000.0
    t = np.arange(40_000) / rate  # 4 s: 0.25 Hz bins
    z = 3.0 * np.exp(2j * np.pi * 5.31 * t) + 2.0 * np.exp(-2j * np.pi * 41.17 * t) + 0.4
    (f1, a1), (f2, a2) = spectral_peaks(z, rate)
    assert f1 == pytest.approx(5.31, abs=1e-3) and f2 == pytest.approx(-41.17, abs=1e-3)
    assert a1 / a2 == pytest.approx(1.5, rel=0.01)


def test_ground_and_box_have_the_size_asked(tmp_path) -> None:
    import json

    path = tmp_path / "flat.json"
    path.write_text(json.dumps({"objects": [{"type": "ground", "center": [5, -3, 0], "size": [120, 40]},
                                            {"type": "box", "center": [20, 0, -1], "size": [2, 4, 2]}]}))
    low, high = open_scene(path).mesh.bounds
    np.testing.assert_allclose([low, high], [[-55.0, -23.0, -2.0], [65.0, 17.0, 0.0]], atol=1e-9)


def test_a_roof_is_a_closed_gable_of_the_size_asked(tmp_path) -> None:
    """A roof object is a closed prism: base size[0] x size[1], ridge size[2] above it, half the box's volume."""
    import json

    path = tmp_path / "roof.json"
    path.write_text(json.dumps({"objects": [{"type": "roof", "center": [0, 0, -3], "size": [8, 6, 2.5]}]}))
    roof = open_scene(path).mesh
    assert roof.is_watertight and roof.is_winding_consistent
    assert abs(roof.volume) == pytest.approx(8 * 6 * 2.5 / 2)
    np.testing.assert_allclose(roof.bounds, [[-4, -3, -5.5], [4, 3, -3]], atol=1e-12)


# Live receivers -------------------------------------------------------------------------------------------
def test_shared_memory_refuses_a_point_count_past_the_block_and_takes_an_empty_frame(tmp_path) -> None:
    from livox_viz import LivoxVizError
    from livox_viz.wire.rflysim import SharedMemoryLink

    path = tmp_path / "RflySim3DImg_0"
    size = 100 * 6 + 37  # room for 100 points
    writer, reader = SharedMemoryLink(path, size, create=True), SharedMemoryLink(path, size)
    try:
        assert writer.write(0.5, np.zeros(6), np.zeros((0, 3), np.int16))
        frame = reader.read()
        assert frame is not None and frame.xyz_int16.shape == (0, 3) and frame.timestamp == 0.5
        assert writer.write(0.6, np.zeros(6), np.ones((100, 3), np.int16))
        block = bytearray(path.read_bytes())
        block[33:37] = (101).to_bytes(4, "little", signed=True)  # PointNum one past the block
        path.write_bytes(bytes(block))
        with pytest.raises(LivoxVizError, match=r"PointNum 101; allowed: 0 to 100, .*\(is --config the sender.s\?\)"):
            reader.read()
    finally:
        writer.close()
        reader.close()


def test_shared_memory_receiver_counts_frames_and_points(tmp_path) -> None:
    from livox_viz.wire.transport import ShmReceiver, ShmSender

    from .conftest import small_config

    config = small_config()
    sender = ShmSender(config, str(tmp_path))
    receiver = ShmReceiver(config, str(tmp_path))
    try:
        got = []
        for k, count in enumerate((7, 0, 30)):
            assert sender.send(0.1 * k, np.zeros(6), np.full((count, 3), k, np.int16)) == 1
            got += receiver.poll()
        assert [len(f.xyz_int16) for f in got] == [7, 0, 30]
        assert (receiver.report.frames, receiver.report.points) == (3, 37)
        assert sender.send(0.4, np.zeros(6), np.full((5, 3), 9, np.int16)) == 1
        streamed = list(receiver.frames(lambda: receiver.report.frames >= 4))
        assert [len(f.xyz_int16) for f in streamed] == [5] and receiver.report.points == 42
    finally:
        sender.close()
        receiver.close()


def test_a_shared_memory_listener_started_before_its_publisher_waits_for_the_block(tmp_path) -> None:
    """As a UDP listener waits for datagrams, one on shared memory waits for the block to appear (it exited with
    'no shared memory block' before); a block of another configuration's size is named, not read."""
    from livox_viz.wire.transport import ShmReceiver, ShmSender

    from .conftest import small_config

    config = small_config()
    receiver = ShmReceiver(config, str(tmp_path))
    sender = None
    try:
        assert receiver.link is None and receiver.poll() == []
        sender = ShmSender(config, str(tmp_path))
        assert sender.send(0.1, np.zeros(6), np.full((4, 3), 2, np.int16)) == 1
        assert [len(f.xyz_int16) for f in receiver.poll()] == [4]
    finally:
        receiver.close()
        if sender is not None:
            sender.close()
    bigger = replace(config, data_width=config.data_width * 2)
    other = ShmReceiver(bigger, str(tmp_path))  # the block there is half the size this configuration needs
    try:
        assert other.poll() == [] and "is --config the sender's?" in other.assembler.last_error
    finally:
        other.close()


def test_shared_memory_sender_waits_for_a_reader_mid_copy_and_drops_the_frame_only_past_its_patience(
        tmp_path) -> None:
    """RflySim's writer never overwrites a block whose flag says a reader is copying it (3). A copy the system
    interrupts for a few milliseconds is waited for; a reader that holds the block past the sender's patience
    costs that frame (an error naming why), and the frame it is copying stays whole."""
    import threading
    import time

    from livox_viz.wire.rflysim import SHM_FLAG_DONE, SHM_FLAG_READING, SHM_FLAG_WRITTEN, SharedMemoryLink
    from livox_viz.wire.transport import ShmSender

    from .conftest import small_config

    config = small_config()
    sender = ShmSender(config, str(tmp_path), patience=0.2)
    reader = SharedMemoryLink(sender.link.path, sender.link.size)
    try:
        assert sender.send(0.1, np.zeros(6), np.full((4, 3), 1, np.int16)) == 1
        reader._map[0] = SHM_FLAG_READING  # a reader descheduled mid-copy, for 30 ms
        threading.Timer(0.03, lambda: reader._map.__setitem__(0, SHM_FLAG_DONE)).start()
        began = time.monotonic()
        assert sender.send(0.2, np.zeros(6), np.full((5, 3), 2, np.int16)) == 1
        assert 0.02 < time.monotonic() - began < 0.2 and sender.errors == 0
        frame = reader.read()
        assert frame.timestamp == 0.2 and frame.xyz_int16.tolist() == [[2, 2, 2]] * 5

        assert sender.send(0.3, np.zeros(6), np.full((6, 3), 3, np.int16)) == 1
        reader._map[0] = SHM_FLAG_READING  # a reader that never lets go
        began = time.monotonic()
        assert sender.send(0.4, np.zeros(6), np.full((7, 3), 4, np.int16)) == 0
        assert time.monotonic() - began >= 0.2
        assert sender.errors == 1 and "still held the previous frame after 200 ms" in sender.last_error
        reader._map[0] = SHM_FLAG_WRITTEN
        frame = reader.read()  # the frame being copied, untouched
        assert frame.timestamp == 0.3 and frame.xyz_int16.tolist() == [[3, 3, 3]] * 6
    finally:
        sender.close()
        reader.close()


def test_udp_receiver_counts_only_its_own_cpu_time() -> None:
    """The listen report's CPU seconds are the time spent on datagrams, never more than the process used."""
    import socket
    import time

    from livox_viz.wire.rflysim import pack_payload, split_datagrams
    from livox_viz.wire.transport import UdpReceiver

    receiver = UdpReceiver("127.0.0.1", 0)
    started = time.process_time()
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            for k in range(20):
                # 6 kB each, 120 kB in all: inside the smallest socket buffer a system gives.
                for datagram in split_datagrams(pack_payload(np.zeros(6), np.ones((1_000, 3), np.int16)), 0.1 * k):
                    sender.sendto(datagram, ("127.0.0.1", receiver.port))
        deadline = time.monotonic() + 10
        frames = []
        while len(frames) < 20 and time.monotonic() < deadline:
            frames += receiver.poll()
        assert len(frames) == 20 and receiver.report.points == 20_000
        assert 0 < receiver.report.cpu_seconds <= time.process_time() - started
    finally:
        receiver.close()
