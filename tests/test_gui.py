"""The window's controller and views, off-screen with small pictures: parameters, playback, files, images."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from livox_viz.widgets.app import LivoxVizApp, render_offscreen  # noqa: E402
from livox_viz.widgets.controls import FRAME_PARAMS, PATTERN_PARAMS  # noqa: E402
from livox_viz.widgets.overlay import WINDOWS, TableSource  # noqa: E402
from livox_viz.widgets.session import Session  # noqa: E402

from livox_viz import PARAM_RANGES, LivoxVizError, SensorConfig, load_preset  # noqa: E402
from livox_viz.config.param_docs import value_bounds  # noqa: E402
from livox_viz.scene.materials import face_materials  # noqa: E402
from livox_viz.scene.scenes import open_scene  # noqa: E402

from .xserver import find_window, private_display, x_tools  # noqa: E402

ROSETTE_PARAMS = PATTERN_PARAMS["rflysim"]

BASELINES = Path(__file__).parent / "baselines"
SIZE = (640, 360)


@pytest.fixture(scope="module")
def urban():
    return open_scene("urban")


@pytest.fixture
def app(urban, tmp_path: Path):
    session = Session(load_preset("livox_mid70"), urban, seed=0, preset_name="livox_mid70")
    application = LivoxVizApp(session, off_screen=True, window_size=SIZE, screenshot_dir=tmp_path / "shots")
    yield application
    application.close()


NEW_VALUES = {
    "camera_fov": 40.0, "petal_height": 4.0, "spacing_exponent": 2.0, "tip_exponent": 0.8,
    "figure8_per_flower": 7.0, "flowers_per_figure": 3.0, "jitter_max_deg": 5.0, "range_max": 100.0,
    "data_width": 100.0, "data_height": 20.0, "data_check_freq": 25.0,
}


@pytest.mark.parametrize("name", ROSETTE_PARAMS + FRAME_PARAMS)
def test_each_parameter_changes_config_and_points(app: LivoxVizApp, name: str) -> None:
    session = app.session
    session.advance_to(0.2)
    before = session.pattern_ring.ordered(session.pattern_ring.positions).copy()
    app.on_param(name, NEW_VALUES[name])
    assert session.config.param_value(name) == pytest.approx(NEW_VALUES[name])
    # The restart empties both views at once: no mix of old and new parameters.
    assert session.pattern_ring.count == 0 and session.scene_ring.count == 0 and session.scan_time == 0
    assert app.pattern_view.poly.n_cells == 0
    session.advance_to(0.2)
    app.refresh()
    after = session.pattern_ring.ordered(session.pattern_ring.positions)
    assert app.pattern_view.poly.n_cells == session.pattern_ring.count == round(0.2 * session.config.point_rate)
    if name != "range_max":
        assert after.shape != before.shape or not np.allclose(after, before)
    radius = np.hypot(after[:, 0], after[:, 1]).max()
    assert radius <= session.config.half_fov_deg + 1e-4


def test_fov_slider_moves_the_drawn_points(app: LivoxVizApp) -> None:
    app.on_param("camera_fov", 30.0)
    app.session.advance_to(0.5)
    app.refresh()
    bounds = app.pattern_view.poly.bounds
    assert max(abs(bounds[0]), abs(bounds[1]), abs(bounds[2]), abs(bounds[3])) == pytest.approx(15.0, abs=0.05)


def test_integer_parameters_snap(app: LivoxVizApp) -> None:
    app.on_param("figure8_per_flower", 6.4)
    assert app.session.config.figure8_per_flower == 6


@pytest.mark.parametrize(("name", "value"), [("camera_fov", 500.0), ("data_width", -3.0), ("petal_height", np.nan)])
def test_a_value_past_its_end_shows_a_message(app: LivoxVizApp, name: str, value: float) -> None:
    config = app.session.config
    assert not app.on_param(name, value)
    assert app.session.config == config
    assert PARAM_RANGES[name].name in app.session.message and "allowed" in app.session.message


def test_control_ranges_are_the_validated_ranges() -> None:
    for name in ROSETTE_PARAMS + PATTERN_PARAMS["risley"] + PATTERN_PARAMS["track"] + FRAME_PARAMS:
        low, high = value_bounds(name)
        assert PARAM_RANGES[name].contains(low) and PARAM_RANGES[name].contains(high)


@pytest.mark.parametrize(("unit", "points"), [("arc", 250), ("petal", 500), ("figure-8", 1000),
                                              ("flower", 10_000), ("frame", 10_000)])
def test_steps_advance_scan_time(app: LivoxVizApp, unit: str, points: int) -> None:
    session = app.session
    session.advance_to(0.0123)
    start = session.pattern.position
    session.step(unit)
    assert session.pattern.position == (start // points + 1) * points
    assert session.scan_time == pytest.approx(session.pattern.position / 100_000)


def test_playback_follows_the_clock(app: LivoxVizApp) -> None:
    session = app.session
    session.playback.set_speed(2.0)
    session.tick(now=100.0)
    session.tick(now=100.25)
    assert session.scan_time == pytest.approx(0.5)
    session.playback.paused = True
    session.tick(now=101.0)
    assert session.scan_time == pytest.approx(0.5)
    assert session.playback.set_speed(50) == 10.0 and session.playback.set_speed(0.0001) == 0.01


@pytest.mark.parametrize("index", range(len(WINDOWS)))
def test_integration_window_drops_old_points(app: LivoxVizApp, index: int) -> None:
    session = app.session
    app.on_window(index)
    session.advance_to(2.5)
    app.refresh()
    ring = session.pattern_ring
    window = WINDOWS[index]
    times = ring.ordered(ring.times)
    expected = 250_000 if window is None else round(window * 100_000)
    assert ring.count == expected == app.pattern_view.poly.n_cells
    assert times.min() >= 2.5 - (window or 2.5) - 1e-9
    scene_times = session.scene_ring.ordered(session.scene_ring.times)
    assert scene_times.min() >= 2.5 - (window or 2.5) - 1e-9
    assert np.all(np.diff(times) > 0)


def test_colour_modes_set_scalars(app: LivoxVizApp) -> None:
    session = app.session
    # Before any point the time bars span the window's length from 0, not 0 to a microsecond.
    assert session.scan_time == 0 and session.pattern_scalar_range() == (0.0, session.window)
    session.display.scene_colour = "time"
    assert session.scene_scalar_range() == (0.0, session.window)
    session.display.scene_colour = "range"
    session.advance_to(0.3)
    assert session.pattern_scalar_range() == (0.0, pytest.approx(0.3))
    for _ in range(4):
        app.cycle_pattern_colour()
        app.refresh()
        live = session.pattern_ring.live_slots()
        values = session.pattern_ring.scalars[live]
        low, high = session.pattern_scalar_range()
        assert values.min() >= low and values.max() <= high
    assert session.display.pattern_colour == "arc" and set(np.unique(values)) == {0, 1, 2, 3}
    app.cycle_scene_colour()
    app.refresh()
    assert session.display.scene_colour == "height"


def test_the_unlimited_window_s_time_bar_spans_the_points_it_holds(app: LivoxVizApp) -> None:
    """The unlimited window holds the last million points (10 s of the Mid-70): at 12.5 s its time bar ran from
    0 s, and a first-use run's two minutes of scan were one flat red."""
    session = app.session
    app.on_window(WINDOWS.index(None))
    session.display.pattern_colour = session.display.scene_colour = "time"
    session.advance_to(12.5)
    app.refresh()
    for ring, bar in ((session.scene_ring, session.scene_scalar_range()),
                      (session.pattern_ring, session.pattern_scalar_range())):
        live = ring.ordered(ring.times)
        assert bar == (pytest.approx(live.min()), pytest.approx(12.5))
        values = ring.scalars[ring.live_slots()]
        assert values.min() >= bar[0] - 1e-3 and values.max() <= bar[1] + 1e-3
    assert bar[0] > 2.0  # the first seconds are no longer held


def test_screenshot_and_sidecar_round_trip(app: LivoxVizApp, tmp_path: Path) -> None:
    from PIL import Image

    app.on_param("petal_height", 3.5)
    app.session.advance_to(0.4)
    first = app.save_screenshot()
    second = app.save_screenshot()
    assert first != second and first.parent == tmp_path / "shots"
    with Image.open(first) as image:
        assert image.size == SIZE
    sidecar = json.loads(first.with_suffix(".json").read_text())
    assert SensorConfig.from_json_dict(sidecar["config"]) == app.session.config
    assert sidecar["seed"] == 0 and sidecar["scan_time_s"] == pytest.approx(0.4)
    assert set(sidecar["cameras"]) == {"pattern", "scene"}
    # Keys pressed since the last render are in the picture as in its sidecar (pyvista renders only once).
    app.cycle_scene_colour()
    app.session.advance_to(0.8)
    third = app.save_screenshot()
    with Image.open(second) as before, Image.open(third) as after:
        changed = np.any(np.asarray(before) != np.asarray(after), axis=2).mean()
    assert changed > 0.01 and json.loads(third.with_suffix(".json").read_text())["scene_colour"] == "height"


def test_read_only_screenshot_folder_keeps_running(app: LivoxVizApp, tmp_path: Path) -> None:
    """A folder with no write bit (refused even to root) and a file where the folder should be: a message each,
    nothing written, the window goes on."""
    read_only = tmp_path / "ro"
    read_only.mkdir()
    read_only.chmod(0o500)
    not_a_folder = tmp_path / "not-a-folder"
    not_a_folder.write_text("a file where the folder should be")
    try:
        messages = {}
        for target in (read_only, not_a_folder):
            app.session.message = ""
            app.screenshot_dir = target
            app.guarded(app.save_screenshot)
            messages[target] = app.session.message
            assert str(target) in messages[target]
        assert "read-only" in messages[read_only]
        # The s key's writer thread says why too, rather than "saving" for ever.
        app.screenshot_dir = read_only
        app.guarded(app.take_screenshot)
        app._writer.shutdown(wait=True)
        assert app.session.message.startswith("screenshot not saved") and "read-only" in app.session.message
        assert list(read_only.iterdir()) == [] and not_a_folder.read_text() == "a file where the folder should be"
    finally:
        read_only.chmod(0o755)


def test_preset_save_and_cycle(app: LivoxVizApp, user_presets: Path) -> None:
    app.on_param("petal_height", 3.3)
    saved = app.save_preset()
    assert saved.parent == user_presets
    assert json.loads(saved.read_text())["otherParams"][1] == 3.3
    assert app.session.message == f"saved preset {saved.stem}"
    (user_presets / "zz_broken.json").write_text("{ not json")
    names = [info.name for info in __import__("livox_viz").list_presets()]
    assert names[-1] == "zz_broken"
    app.session.set_config(load_preset("livox_mid70"), "livox_mid70")
    app._preset_cursor = -1
    seen = []
    for _ in range(len(names)):
        before = app.session.config
        app.guarded(app.next_preset)
        seen.append((app.session.preset_name, app.session.message, app.session.config == before))
    broken = [entry for entry in seen if "zz_broken" in entry[1]]
    # The broken preset leaves the configuration as it was and says which file and why.
    assert len(broken) == 1 and "malformed JSON" in broken[0][1] and broken[0][2]
    loaded = {name for name, message, _ in seen if message == f"preset {name}"}
    assert loaded == set(names) - {"zz_broken"}


def _changed_fraction(a: np.ndarray, b: np.ndarray, tolerance: int = 24) -> float:
    """The share of pixels whose colour differs by more than ``tolerance`` in any channel."""
    assert a.shape == b.shape
    return float((np.abs(a.astype(int) - b.astype(int)).max(axis=-1) > tolerance).mean())


def _image(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as image:
        return np.asarray(image.convert("RGB"))


#: Most pixels a render may differ from its baseline by (software GL is deterministic; fonts may shift a little).
CHANGED_LIMIT = 0.002


@pytest.mark.parametrize("view", ["pattern", "scene", "risley", "band", "panorama"])
def test_image_regression(urban, tmp_path: Path, view: str) -> None:
    """Compares only; the baselines are renewed by their own step (tests/baseline_images.py)."""
    from tests.baseline_images import render_view

    if os.environ.get("LIVOX_VIZ_UPDATE_BASELINES"):
        pytest.fail("the image test never writes baselines: run `make baselines`, look at them, commit them")
    out = render_view(view, tmp_path / f"{view}.png", urban)
    baseline = BASELINES / f"{view}.png"
    changed = _changed_fraction(_image(out), _image(baseline))
    assert changed < CHANGED_LIMIT, f"{view}: {100 * changed:.2f} % of the pixels differ from {baseline}"


def test_image_regression_sees_a_missing_vehicle(urban, tmp_path: Path) -> None:
    """The comparison fails when the vehicle, the FOV cone and the sensor are not drawn."""
    session = Session(load_preset("livox_mid70"), urban, seed=0, preset_name="livox_mid70")
    app = LivoxVizApp(session, off_screen=True, window_size=(480, 360), views="scene")
    plotter = app.plotters["scene"]
    try:
        # Numbers before pictures: the actors sit where the pose says.
        sensor = session.sensor_pose.origin
        centre = np.array(plotter.actors["sensor"].GetCenter())
        np.testing.assert_allclose(centre, sensor * [1, -1, -1], atol=1e-6)
        for name in ("vehicle", "fov-cone", "sensor"):
            plotter.actors[name].SetVisibility(False)
        session.advance_to(0.5)
        image = app.current_image()
    finally:
        app.close()
    assert _changed_fraction(image, _image(BASELINES / "scene.png")) > CHANGED_LIMIT


def test_image_regression_sees_another_scan_time(urban, tmp_path: Path) -> None:
    other = tmp_path / "pattern-other.png"
    render_offscreen(Session(load_preset("livox_mid70"), urban, seed=0), 0.1, other, views="pattern", size=(480, 360))
    assert _changed_fraction(_image(other), _image(BASELINES / "pattern.png")) > CHANGED_LIMIT


def test_a_new_mount_moves_the_drawn_sensor(app: LivoxVizApp, tmp_path: Path, seed_json: dict) -> None:
    """Loading a preset whose sensor sits elsewhere moves the sensor, its cone and the rays together."""
    from dataclasses import replace

    moved = replace(app.session.config, sensor_pos_xyz=(2.0, 0.0, -3.0))
    app.session.set_config(moved, "moved")
    app.refresh()
    expected = app.session.vehicle_pose.compose(__import__("livox_viz.core.poses", fromlist=["Pose"]).Pose(
        (2.0, 0.0, -3.0))).origin
    np.testing.assert_allclose(app.session.sensor_pose.origin, expected, atol=1e-12)
    to_display = np.array([1, -1, -1])
    actors = app.plotters["scene"].actors
    np.testing.assert_allclose(actors["sensor"].GetCenter(), expected * to_display, atol=1e-6)
    cone = actors["fov-cone"]
    apex = np.array(cone.user_matrix) @ [0.0, 0.0, 0.0, 1.0]
    np.testing.assert_allclose(apex[:3], expected * to_display, atol=1e-9)  # the cone starts at the sensor
    assert np.linalg.norm(np.asarray(cone.GetMapper().GetInput().points), axis=1).max() == pytest.approx(1.6)
    # The rays come from the same place: every decoded point lies farther from the new origin than 0.
    app.session.advance_to(0.2)
    ring = app.session.scene_ring
    assert ring.count > 0 and app.session.mounted.sensor_pose.origin.tolist() == expected.tolist()


def test_the_gui_cloud_is_the_scan_commands_cloud(urban, tmp_path: Path) -> None:
    """One casting path: the decoded cloud the window shows equals what 'livox-viz scan' writes."""
    from livox_viz.cli import main

    out = tmp_path / "scan.npz"
    assert main(["scan", "--scene", "urban", "--seconds", "0.3", "--seed", "5", "--out", str(out)]) == 0
    data = np.load(out)
    session = Session(load_preset("livox_mid70"), urban, seed=5)
    session.set_window(WINDOWS.index(None))
    session.advance_to(0.3)
    ring = session.scene_ring
    shown = ring.ordered(ring.positions)
    pose = data["frame_pose"][0, 1:7]
    from livox_viz.core.poses import Pose

    sensor = Pose(tuple(pose[:3]), *pose[3:])
    expected = sensor.origin + data["xyz_sensor"] @ sensor.rotation.T
    assert shown.shape == expected.shape
    np.testing.assert_allclose(shown, expected, atol=1e-4)  # float32 rings
    np.testing.assert_array_equal(ring.ordered(ring.times), data["t"])


@pytest.mark.xdist_group("x-server")  # one X server at a time (see tests/test_window.py)
def test_real_window_under_xvfb(tmp_path: Path) -> None:
    _, xdotool = x_tools()
    with private_display("1600x900x24") as display:
        _real_window(tmp_path, xdotool, display)


def _real_window(tmp_path: Path, xdotool: str, display: str) -> None:
    env = {**os.environ, "DISPLAY": display, "LIVOX_VIZ_PRESETS": str(tmp_path / "presets")}
    env.pop("WAYLAND_DISPLAY", None)
    # The window's output goes to files: a pipe nobody reads while we wait for the window stops the program at
    # its 64 KiB-th byte, and a failure below then says what the program printed.
    (tmp_path / "work").mkdir()
    with open(tmp_path / "gui.out", "w+") as out, open(tmp_path / "gui.err", "w+") as err:
        gui = subprocess.Popen([sys.executable, "-m", "livox_viz", "gui", "--size", "1200x700"], cwd=tmp_path / "work",
                               env=env, stdout=out, stderr=err, text=True)

        def printed() -> str:
            err.seek(0)
            return f"exit status {gui.poll()}; it printed: {err.read()[-3000:]!r}"

        try:
            window = find_window(xdotool, env, "^livox-viz - ", gui)
            assert window, f"the livox-viz window did not appear: {printed()}"
            title = subprocess.run([xdotool, "getwindowname", window[0]], env=env, capture_output=True, text=True,
                                   timeout=10).stdout.strip()
            assert title == "livox-viz - livox_mid70"
            # No window manager here: give the window the keyboard, then type as a user does (XTEST).
            subprocess.run([xdotool, "windowfocus", "--sync", window[0]], env=env, check=True, timeout=10)
            time.sleep(2.0)
            # e and q are also VTK's own keys, 3 its stereo: the window stays (the screenshot after them proves it).
            for key in ("space", "space", "3", "Right", "c", "e", "s", "p"):
                subprocess.run([xdotool, "key", key], env=env, check=True, timeout=10)
                time.sleep(0.5)
            time.sleep(1.0)
            subprocess.run([xdotool, "key", "q"], env=env, check=True, timeout=10)
            gui.wait(timeout=60)
            assert gui.returncode == 0, printed()
        finally:
            if gui.poll() is None:
                gui.kill()
                gui.wait()
    shots = list((tmp_path / "work" / "screenshots").glob("livox-viz-*.png"))
    assert len(shots) == 1 and shots[0].with_suffix(".json").exists()
    sidecar = json.loads(shots[0].with_suffix(".json").read_text())
    # Right paused the scan; c moved the colouring on from time.
    assert sidecar["paused"] and sidecar["pattern_colour"] == "figure-8"
    assert len(list((tmp_path / "presets").glob("*.json"))) == 1


def test_reference_overlay_plays_in_step(app: LivoxVizApp) -> None:
    from livox_viz import ScanPattern
    from livox_viz.fitting.reference import ReferencePattern

    session = app.session
    app.guarded(app.toggle_reference)
    assert "no reference" in session.message
    xy = ScanPattern(session.config, seed=0).take(200_000).xy_deg
    session.overlay.set_source(TableSource(ReferencePattern("same", xy, np.arange(len(xy)) / 1e5, 1e5)), 0.0)
    session.advance_to(0.7)
    app.refresh()
    ring = session.overlay.ring
    assert ring.count == 50_000 == app.pattern_view.reference_poly.n_cells
    # The same pattern as reference: identical points, identical coverage.
    ours = session.pattern_ring
    np.testing.assert_array_equal(ring.ordered(ring.positions), ours.ordered(ours.positions))
    assert session.overlay.coverage() == pytest.approx(session.visible_coverage())
    app.cycle_reference_window()
    session.advance_to(1.9)
    assert session.overlay.ring.count == 100_000  # its own 1 s window; the table loops after 2 s
    app.toggle_reference()
    app.refresh()
    assert not app.pattern_view.reference_actor.GetVisibility()


class QueuedFrames:
    """A live view's source whose frames the test queues: each poll hands over what is queued."""

    def __init__(self, frames: list | None = None) -> None:
        self.queue: list = list(frames or [])

    def poll(self) -> list:
        frames, self.queue = self.queue, []
        return frames


def test_received_frames_feed_the_views(app: LivoxVizApp) -> None:
    from livox_viz.casting.scan import LidarScanner
    from livox_viz.wire.rflysim import LivoxFrame

    session = app.session
    scanner = LidarScanner(session.config, session.caster, session.vehicle_pose, seed=0)
    sent = [scanner.next_frame() for _ in range(3)]

    session.restart()
    session.source = QueuedFrames([LivoxFrame(f.timestamp, f.sensor_pose.as_array(), f.xyz_int16) for f in sent])
    added = session.tick()
    app.refresh()
    assert added == sum(len(f) for f in sent) == session.scene_ring.count
    np.testing.assert_allclose(session.scene_ring.ordered(session.scene_ring.positions),
                               np.concatenate([f.xyz_world_decoded for f in sent]), atol=1e-3)
    # Angles come back from the int16 points: off by up to about the 18 mm step over the range.
    shown = session.pattern_ring.ordered(session.pattern_ring.positions)[:, :2]
    true = np.concatenate([f.xy_deg for f in sent])
    ranges = np.concatenate([f.range_m for f in sent])
    bound = np.degrees(2.0 * 600 / 32767 / ranges) + 1e-3
    assert np.all(np.abs(shown - true).max(axis=1) <= bound)
    assert session.frame_index == 2 and session.scan_time == pytest.approx(0.3)


def test_the_live_view_s_charts_show_the_stream_s_own_curves(app: LivoxVizApp, monkeypatch) -> None:
    """A trial saw the live view's charts draw the preset's model curves, not the stream's: a stream of another
    pattern (the CameraFOV halved) now gives the charts its own coverage, computed from the points received, and
    the model's curves go at the first tick of the live view; with nothing new the curves stand."""
    from livox_viz.widgets import charts as charts_module

    from livox_viz.casting.scan import LidarScanner
    from livox_viz.patterns.metrics import received_curves
    from livox_viz.wire.rflysim import LivoxFrame

    monkeypatch.setattr(charts_module, "STREAM_CURVES_EVERY_S", 0.0)
    session = app.session
    model = app.charts.ours
    assert model is not None and app.charts.ours_coverage.visible
    narrow = session.config.with_param("camera_fov", 35.0)
    scanner = LidarScanner(narrow, session.caster, session.vehicle_pose, seed=0)
    sent = [LivoxFrame(f.timestamp, f.sensor_pose.as_array(), f.xyz_int16) for f in
            (scanner.next_frame() for _ in range(4))]

    session.restart()
    session.source = QueuedFrames()
    app.charts.update()
    assert app.charts.ours is None and not app.charts.ours_coverage.visible  # the model's curves went
    session.source.queue = sent
    session.tick()
    app.charts.update()
    app.charts.finish()
    stream = app.charts.ours
    assert stream is not None and app.charts.ours_coverage.visible
    assert re.fullmatch(r"stream \(its 0\.[34]\d* s\)", app.charts.ours_coverage.label), app.charts.ours_coverage.label
    assert app.charts.ours_density.label == "stream"
    ring = session.pattern_ring
    expected = received_curves(ring.ordered(ring.positions)[:, :2].astype(float), ring.ordered(ring.times),
                               session.config.point_rate, session.config.field_of_view)
    np.testing.assert_allclose(stream.coverage, expected.coverage)
    # Frames of 0.1 s, each stamped with one time: no integration time shorter than a frame is drawn.
    np.testing.assert_array_equal(stream.seconds, [0.1, 0.2, 0.3])
    # The stream's scan covers only the middle of the preset's field of view: far less than the model at 0.3 s.
    at = list(model.seconds).index(0.3)
    assert stream.coverage[-1] < 0.5 * model.coverage[at], (stream.coverage, model.coverage)
    app.charts.update()
    assert app.charts._ours_pending is None  # nothing new arrived: nothing asked again


def test_the_live_view_says_its_rate_sender_and_a_stop_and_a_pause_sets_frames_aside(app: LivoxVizApp) -> None:
    """gui --listen (issue 45): the text says where it listens and who sends, how fast frames and points come (the
    figures of the frames that came), when the stream stopped; frames that come while paused are read and set
    aside, so play resumes with the stream as it is (left in the socket, they came back as a burst of old frames)."""
    from livox_viz.widgets.live import LiveStats

    from livox_viz.casting.scan import LidarScanner
    from livox_viz.wire.rflysim import LivoxFrame

    session = app.session
    scanner = LidarScanner(session.config, session.caster, session.vehicle_pose, seed=0)
    sent = [LivoxFrame(f.timestamp, f.sensor_pose.as_array(), f.xyz_int16, source="127.0.0.1:5000")
            for f in (scanner.next_frame() for _ in range(4))]

    session.restart()
    session.source = QueuedFrames()
    session.live = LiveStats("udp 0.0.0.0:9999")
    assert session.live_line() == "live: udp 0.0.0.0:9999: waiting for the first frame"
    session.playback.paused = True
    session.source.queue = sent[:2]
    assert session.tick() == 0 and session.scene_ring.count == 0 and session.source.queue == []
    assert session.live.paused_frames == 2
    with pytest.raises(LivoxVizError, match="the live view draws the frames as the sender made them"):
        app.set_returns_model("datasheet")  # a trial's d reset the live view's clock and changed nothing it drew
    session.playback.paused = False
    session.source.queue = sent[2:]
    assert session.tick() == sum(f.xyz_int16.shape[0] for f in sent[2:]) == session.scene_ring.count
    app.refresh()
    assert "live: udp 0.0.0.0:9999 <- 127.0.0.1:5000, " in app.hud.state.GetText(2)

    # The figures, on a clock of our own: 10 frames of 1,000 points a second for 3 s, then nothing.
    live = LiveStats("udp 0.0.0.0:9999")

    class Frame:
        source = "10.0.0.2:4000"
        xyz_int16 = np.zeros((1000, 3), np.int16)

    for k in range(30):
        live.heard([Frame()], 100.0 + k / 10)
    assert live.line(102.95, 10.0) == "live: udp 0.0.0.0:9999 <- 10.0.0.2:4000, 10.0 frames/s, 10,000 pts/s"
    assert live.line(102.95, 10.0, lost=3).endswith(", 3 lost")
    # 0.6 s quiet at 10 Hz is no stop yet: the rates count the last 2 s, which hold 15 frames.
    assert live.line(103.5, 10.0).endswith(", 7.5 frames/s, 7,500 pts/s")
    assert live.line(106.9, 10.0) == "live: udp 0.0.0.0:9999 <- 10.0.0.2:4000: no frame for 4 s (30 frames received)"
    assert live.stopped_for(102.2, 1.0) is None  # at 1 Hz, 3 s of quiet are the stream's own pace


def test_the_background_compiles_the_datasheet_loops_before_the_risley_loops() -> None:
    """A first-use trial pressed d at once, with an empty cache, and waited while the Risley loops (which the
    default rosette does not use) compiled first: the datasheet's come first, the likeliest next need."""
    from livox_viz.widgets.warmup import LoopWarmer

    assert LoopWarmer(now=("ideal",)).later == ["datasheet", "risley", "motion"]
    assert LoopWarmer(now=("risley", "ideal")).later == ["datasheet", "motion"]


@pytest.mark.parametrize("background", ["white", "dark"])
def test_the_density_image_s_empty_cells_show_the_background_and_what_is_behind(app: LivoxVizApp,
                                                                               background: str) -> None:
    """Empty cells were painted the dark background's colour: an opaque square hid the reference drawn behind
    (a first-use trial), and stood dark on a white background. A corner of the image, outside the rosette's
    circle, must be the background itself."""
    import pyvista as pv
    import vtk
    from livox_viz.widgets.views import BACKGROUNDS

    session = app.session
    session.display.drawing = "density"
    session.advance_to(0.5)
    app.pattern_view.set_background(background)
    app.refresh()
    assert app.pattern_view.density_actor.GetVisibility()
    x0, x1, y0, y1 = session.density.bounds
    corner = vtk.vtkCoordinate()
    corner.SetCoordinateSystemToWorld()
    corner.SetValue(x0 + 0.03 * (x1 - x0), y0 + 0.03 * (y1 - y0), 0.0)
    px, py = corner.GetComputedDisplayValue(app.pattern_view.renderer)
    image = app.plotters["pattern"].screenshot(None, return_img=True)
    drawn = image[image.shape[0] - 1 - py, px, :3].astype(float)
    expected = np.array(pv.Color(BACKGROUNDS[background][0]).int_rgb, dtype=float)
    assert np.abs(drawn - expected).max() <= 3, (drawn, expected)


def test_a_parameter_changed_while_paused_shows_the_new_scan_at_the_time_shown(app: LivoxVizApp, urban) -> None:
    """Tuning while paused: the scan restarted at t = 0, still paused, and the view stayed empty until play (a
    first-use trial). Now it holds what the new configuration's scan played to the time shown holds."""
    session = app.session
    session.advance_to(1.0)
    session.playback.paused = True
    assert app.on_param("petal_height", 4.0)
    while session.filling is not None:  # a window filled over ticks
        session.tick()
    assert session.playback.paused and session.shown_time == pytest.approx(1.0)
    fresh = Session(session.config, urban, seed=0, preset_name="livox_mid70")
    fresh.advance_to(1.0)
    assert session.pattern_ring.count == fresh.pattern_ring.count > 0
    for ring, again in ((session.pattern_ring, fresh.pattern_ring), (session.scene_ring, fresh.scene_ring)):
        np.testing.assert_array_equal(ring.ordered(ring.positions), again.ordered(again.positions))
    session.playback.paused = False  # playing, a change starts from t = 0 as before
    assert app.on_param("petal_height", 3.0)
    assert session.scan_time == 0.0 and session.pattern_ring.count == 0


def test_density_image_follows_the_window(app: LivoxVizApp) -> None:
    from livox_viz.patterns.metrics import coverage

    session = app.session
    app.on_window(0)  # 0.1 s
    for t in (0.05, 0.1, 0.17, 0.26):
        session.advance_to(t)
        ring = session.pattern_ring
        live = ring.ordered(ring.positions)
        assert session.density.counts.sum() == ring.count == live.shape[0]
        expected = np.zeros_like(session.density.counts)
        np.add.at(expected.reshape(-1), session.density.cells(live), 1.0)
        np.testing.assert_array_equal(session.density.counts, expected)
        assert session.visible_coverage() == pytest.approx(coverage(live[:, :2].astype(float), 35.216))
    session.display.drawing = "density"
    app.refresh()
    assert app.pattern_view.density_actor.GetVisibility() and not app.pattern_view.actor.GetVisibility()
    assert app.pattern_view.density_image.point_data["density"].max() == pytest.approx(
        np.log1p(session.density.counts.max()))
    # The bar's colours are log(1 + count); its marks are counts, each where its colour is.
    bar, table = app.pattern_view.scalar_bar, app.pattern_view.density_lut
    assert bar.GetDrawAnnotations() and bar.GetNumberOfLabels() == 0
    marks = {text: value for value, text in table.annotations.items()}
    assert marks["0"] == 0.0 and marks["1"] == pytest.approx(math.log(2.0)) and len(marks) >= 3
    assert all(value == pytest.approx(math.log1p(float(text.replace(",", "")))) for text, value in marks.items())
    assert max(marks.values()) <= table.scalar_range[1] + 1e-9
    session.display.drawing = "auto"
    app.refresh()
    assert app.pattern_view.actor.GetVisibility()  # 10 000 points < the view's pixels
    # Back to the points' time colours: the bar is marked with the window's own start and end.
    assert bar.GetLookupTable() is app.pattern_view.actor.mapper.lookup_table
    table = bar.GetLookupTable()
    marks = sorted(table.GetAnnotatedValue(k).ToFloat() for k in range(table.GetNumberOfAnnotatedValues()))
    assert marks[0] == pytest.approx(0.16) and marks[-1] == pytest.approx(0.26)


def test_scene_cycle_survives_a_broken_mesh(app: LivoxVizApp, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import trimesh

    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "a_broken.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    trimesh.creation.box((4, 4, 4)).export(folder / "b_box.obj")
    (folder / "c_gone.materials.json").write_text('{"wall": 0.2}')  # a sidecar (of no mesh here), not a scene
    monkeypatch.setenv("LIVOX_VIZ_SCENES", str(folder))
    session = app.session
    session.scene_options = {"up": "z", "reflectance": 0.9}  # the window's --reflectance
    seen = []
    for _ in range(6):
        app.guarded(app.cycle_scene)
        seen.append((session.scene.name, session.message))
        if session.scene.name == "b_box.obj":
            assert np.all(face_materials(session.scene.mesh)[0] == 0.9)
    names = [name for name, _ in seen]
    assert {"dense_terrain", "open_field", "b_box.obj"} <= set(names) and "c_gone.materials.json" not in names
    assert not any("objects" in message for _, message in seen)
    assert any("NaN or infinite" in message for _, message in seen)
    session.advance_to(0.1)
    app.refresh()
    assert app.scene_view._scene_shown is session.scene
    assert app.scene_view.scene_actor.GetMapper().GetInput().n_cells == len(session.scene.mesh.faces)


def test_risley_preset_parameters_and_model_switch(app: LivoxVizApp) -> None:
    session = app.session
    app.guarded(app.toggle_pattern_model)
    assert "no Risley track" in session.message and session.config.pattern_model == "rflysim"
    session.set_config(load_preset("livox_mid70_risley"), "livox_mid70_risley")
    assert session.config.param_value("prism_rpm_a") == pytest.approx(4664.0)
    assert session.display.step_unit == "frame"
    session.advance_to(0.1)
    reach = np.hypot(*session.pattern_ring.ordered(session.pattern_ring.positions)[:, :2].T).max()
    app.on_param("deflection_a", 8.0)
    assert session.config.risley.deflection_deg[0] == 8.0
    session.advance_to(0.1)
    smaller = np.hypot(*session.pattern_ring.ordered(session.pattern_ring.positions)[:, :2].T).max()
    assert smaller < reach - 8.0  # the outer rim moved in with prism A's deflection
    app.toggle_pattern_model()
    assert session.config.pattern_model == "rflysim"
    app.toggle_pattern_model()
    assert session.config.pattern_model == "risley" and session.config.risley.deflection_deg[0] == 8.0


def test_the_reference_is_drawn_in_a_colour_no_pattern_colouring_uses(app: LivoxVizApp) -> None:
    """A first-use trial could not tell the reference (light blue) from our older points (the time map's blues).
    It is a neutral grey now, in the view, the charts and the header's words; no colouring of ours is grey."""
    import pyvista as pv
    from livox_viz.widgets.views import CATEGORY_COLOURS

    app.cycle_reference()
    app.refresh()
    drawn = np.array(app.pattern_view.reference_actor.prop.color.float_rgb)
    assert drawn.max() - drawn.min() < 0.02 and drawn.min() > 0.8  # light and without hue
    lut = pv.LookupTable(cmap=app.pattern_view.colour_map, n_values=256)
    for colour in [*(np.array(lut.values[k, :3]) / 255 for k in range(256)),
                   *(np.array(pv.Color(c).float_rgb) for c in CATEGORY_COLOURS)]:
        assert np.abs(colour - drawn).max() > 0.15, colour
    line = np.array(pv.Color(app.charts.reference_coverage.color).float_rgb)
    assert line.max() - line.min() < 0.02
    app.pattern_view.set_background("white")  # there the light grey vanished: a dark one
    assert max(app.pattern_view.reference_actor.prop.color.float_rgb) < 0.4
    app.pattern_view.set_background("dark")
    assert np.allclose(app.pattern_view.reference_actor.prop.color.float_rgb, drawn)
    assert f"reference {app.session.overlay.source.name} (grey)" in app.hud.pattern_text(app.session)


def _contrast(first, second) -> float:
    """WCAG's contrast ratio of two RGB colours (0-1 each): 1 (the same) to 21 (black on white)."""
    def luminance(rgb) -> float:
        linear = [c / 12.92 if c <= 0.03928 else ((c + 0.055) / 1.055) ** 2.4 for c in rgb]
        return 0.2126 * linear[0] + 0.7152 * linear[1] + 0.0722 * linear[2]

    high, low = sorted((luminance(first), luminance(second)), reverse=True)
    return (high + 0.05) / (low + 0.05)


@pytest.mark.parametrize("background", ["dark", "gradient", "black", "white"])
def test_the_grid_marks_and_colour_bars_read_on_every_background(app: LivoxVizApp,
                                                                  background: str) -> None:
    """A first-use trial could not read "20°" over a dense rosette: the marks were bare grey text among the
    points. Each now stands on a mostly opaque patch of the background, its text legible on it (WCAG's 4.5:1)."""
    import pyvista as pv
    from livox_viz.widgets.views import BACKGROUNDS

    app.pattern_view.set_background(background)
    app.refresh()
    actor = app.pattern_view.renderer.actors["grid-labels-labels"]
    placer = actor.GetMapper()
    assert placer.GetShape() != placer.NONE and placer.GetStyle() == placer.FILLED
    patch = placer.GetBackgroundColor()
    assert np.allclose(patch, pv.Color(BACKGROUNDS[background][0]).float_rgb)
    assert placer.GetBackgroundOpacity() >= 0.7
    text = placer.GetInputAlgorithm().GetTextProperty().GetColor()
    assert _contrast(text, patch) >= 4.5, (background, text, patch)
    assert app.pattern_view.guide_labels == ["10°", "20°", "30°"]
    # The colour bars' words too: light grey, "points/cell" vanished on white; and each on its patch, whatever is
    # drawn under it (bare, the return/tag legend's words were faint over the grey buildings and the cloud).
    app.scene_view.show_axes(True)
    for view in (app.pattern_view, app.scene_view):
        view.set_background(background)
        bar = view.scalar_bar
        words_shown = [bar.GetTitleTextProperty(), bar.GetLabelTextProperty(), bar.GetAnnotationTextProperty()]
        if view is app.scene_view:
            words_shown += [name.GetTextProperty() for name in view.trihedron.names]
        for words in words_shown:
            assert _contrast(words.GetColor(), patch) >= 4.5, (background, words.GetColor())
            opacity, backing = words.GetBackgroundOpacity(), words.GetBackgroundColor()
            for under in ((0.0, 0.0, 0.0), (1.0, 1.0, 1.0)):
                behind = [opacity * b + (1 - opacity) * u for b, u in zip(backing, under, strict=True)]
                assert _contrast(words.GetColor(), behind) >= 4.5, (background, under, opacity)


def test_the_scene_s_axes_are_named_in_the_corner_apart_from_every_camera(app: LivoxVizApp) -> None:
    """From the side camera the world axes' X, Y and Z merged into one blob (a first-use trial): VTK named the 5 m
    axes at their tips, a few pixels apart when seen from far off or end on. The axes at the origin are now
    unnamed, and the corner's axes, a fixed size, name theirs at least TRIHEDRON_NAMES_APART_PX apart, inside the
    view, whichever way each camera looks; their tips turn with the camera."""
    from itertools import combinations

    from livox_viz.widgets.views import CAMERA_PRESETS, TRIHEDRON_NAMES_APART_PX

    view = app.scene_view
    view.show_axes(True)
    assert view.axes_actor.GetAxisLabels() == 0
    width, height = view.renderer.GetSize()
    seen = set()
    for camera in CAMERA_PRESETS:
        app.set_scene_camera(camera)
        app.render(every=True)
        names = view.trihedron.name_positions()
        for first, second in combinations(range(3), 2):
            assert np.hypot(*(names[first] - names[second])) >= TRIHEDRON_NAMES_APART_PX - 1, (camera, names)
        assert np.all(names > 8) and np.all(names < (width - 8, height - 8)), (camera, names)
        seen.add(tuple(np.round(names.ravel())))
    assert len(seen) == len(CAMERA_PRESETS)  # they turn with the camera
    view.show_axes(False)
    assert view.trihedron is None and view.axes_actor is None


def test_charts_follow_the_parameters_and_the_reference(app: LivoxVizApp) -> None:
    from livox_viz.widgets.overlay import PresetSource

    from livox_viz.patterns.metrics import config_curves

    session, charts = app.session, app.charts
    np.testing.assert_allclose(charts.ours_coverage.y, 100 * config_curves(session.config).coverage)
    assert not charts.reference_coverage.visible
    app.cycle_reference()
    app.refresh()
    app.charts.finish()  # the reference's curves are made on a worker
    source = session.overlay.source
    first = app.reference_choices()[0]
    assert isinstance(source, PresetSource) and source.name == first
    assert {"livox_mid40_risley", "livox_horizon", "livox_avia"} <= set(app.reference_choices())
    assert "livox_mid360" not in app.reference_choices()  # another plane: its angles are not ours
    expected = config_curves(load_preset(first))
    np.testing.assert_allclose(charts.reference_coverage.y, 100 * expected.coverage)
    np.testing.assert_allclose(charts.reference_density.y, expected.density / 1e6)
    assert charts.reference_coverage.visible
    before = np.array(charts.ours_coverage.y)
    app.on_param("jitter_max_deg", 8.0)
    assert np.array_equal(charts.ours_coverage.y, before)  # on the worker: the change did not wait for them
    charts.finish()
    after = np.array(charts.ours_coverage.y)
    np.testing.assert_allclose(after, 100 * config_curves(session.config).coverage)
    assert not np.allclose(before, after)


def test_e_offers_the_reference_table_again_in_its_round(app: LivoxVizApp) -> None:
    """With --reference mid70, e went through the presets to "no reference" and never back to the table."""
    from livox_viz.widgets.overlay import TableSource

    from livox_viz.fitting.reference import load_reference

    session = app.session
    table = TableSource(load_reference("mid70"))
    app.set_reference(table)
    seen = []
    for _ in range(len(app.reference_choices()) + 2):
        app.cycle_reference()
        source = session.overlay.source
        seen.append(None if source is None else source.name)
    assert seen[-2] is None and session.overlay.source is table  # round: presets, none, the table again
    assert seen[:-2] == app.reference_choices()


def test_a_reference_preset_waits_only_for_its_pattern_s_loops(app: LivoxVizApp) -> None:
    """A reference plays only its pattern: the Avia's, a preset with datasheet returns, waited in a first-use
    run for the datasheet loops (a minute on an empty cache) it never uses."""
    asked: dict[str, set[str]] = {}

    def defer(stages: set[str], action, what: str, kind: str) -> bool:
        asked[what] = set(stages)
        return True  # as if loaded: e goes on to the next

    app.defer = defer
    try:
        for _ in app.reference_choices():
            app.cycle_reference()
    finally:
        app.defer = None
    assert set(asked) == {f"reference {name}" for name in app.reference_choices()}
    assert load_preset("livox_avia").returns_model == "datasheet"
    assert asked["reference livox_avia"] == {"risley"}
    assert all(stages <= {"risley"} for stages in asked.values()), asked


def test_fit_key_moves_the_parameters_to_the_reference(app: LivoxVizApp) -> None:
    from livox_viz import ScanPattern
    from livox_viz.fitting.reference import ReferencePattern

    session = app.session
    truth = session.config.with_param("petal_height", 4.0).with_param("spacing_exponent", 1.7)
    xy = ScanPattern(truth, seed=3).take(150_000).xy_deg
    session.overlay.set_source(TableSource(ReferencePattern("truth", xy, np.arange(len(xy)) / 1e5, 1e5)), 0.0)
    app.guarded(app.fit_to_reference)
    assert "fitting the rosette to truth" in session.message  # on a worker: the window plays on
    app.guarded(app.fit_to_reference)
    assert "fitting to truth already" in session.message
    app.tick()
    assert app.finish_fit()
    assert "fitted to truth" in session.message and "warning" not in session.message
    assert session.config.petal_height == pytest.approx(4.0, abs=1e-3)
    assert session.config.spacing_exponent == pytest.approx(1.7, abs=1e-3)


def test_a_fit_far_off_the_reference_s_petals_is_applied_with_a_warning(app: LivoxVizApp) -> None:
    """A trial's f fitted the rosette to the HAP's band, 3.05 deg rms off, and said only "fitted": now the message
    says how rough it is and that a rosette cannot draw that scan (the fit is applied all the same: Ctrl+Z)."""
    import time
    from concurrent.futures import Future
    from types import SimpleNamespace

    from livox_viz.fitting.rosette_fit import ShapeFit

    session = app.session
    rough = session.config.with_param("petal_height", 6.0)
    done: Future = Future()
    done.set_result(SimpleNamespace(config=rough, shape=ShapeFit(
        camera_fov=107.6, petal_height=6.0, spacing_exponent=1.3, tip_exponent=1.1, rms_deg=3.054, p95_deg=6.0,
        points_per_arc=10.0, petals=40)))
    app._fit = (done, "livox_hap", time.perf_counter())
    assert app.finish_fit()
    assert session.config.petal_height == pytest.approx(6.0)
    assert "fitted to livox_hap" in session.message
    assert "warning: the rosette follows the reference only roughly: 3.05 deg rms off its petals" in session.message


def test_a_moving_vehicle_is_followed_and_its_cloud_frame_switches(urban) -> None:
    from livox_viz.motion.flights import builtin_trajectory

    trajectory = builtin_trajectory("line", 8.0, urban.vehicle_pose, 3.0)
    session = Session(load_preset("livox_mid70"), urban, seed=0, trajectory=trajectory)
    app = LivoxVizApp(session, off_screen=True, window_size=SIZE)
    try:
        camera_before = np.array(app.scene_view.renderer.camera.position)
        session.advance_to(1.0)
        app.refresh()
        actors = app.plotters["scene"].actors
        moved = np.array(actors["vehicle"].user_matrix)[:3, 3]
        expected = trajectory.pose_at(1.0).origin * [1, -1, -1]
        np.testing.assert_allclose(moved, expected, atol=1e-9)
        np.testing.assert_allclose(np.array(app.scene_view.renderer.camera.position) - camera_before,
                                   expected - urban.vehicle_pose.origin * [1, -1, -1], atol=1e-9)
        assert "path" in actors
        world = session.scene_ring.ordered(session.scene_ring.positions).copy()
        app.toggle_cloud_frame()
        assert session.display.cloud_frame == "sensor" and session.scan_time == pytest.approx(1.0)
        smeared = session.scene_ring.ordered(session.scene_ring.positions)
        # The same returns, placed differently: up to the distance flown in a chunk apart.
        assert smeared.shape == world.shape and 0.01 < np.abs(smeared - world).max() < 8.0 * 0.5
        session.playback.paused = False
        session.advance_to(5.0)  # past the end of the flight: it stops there
        assert session.scan_time == pytest.approx(3.0) and session.playback.paused
        assert "end of the trajectory" in session.message
    finally:
        app.close()


def test_the_window_and_render_start_as_their_command_lines_say(tmp_path: Path) -> None:
    """``--scene-colour``, ``--reflectance`` and ``--up`` reach the session: the cloud's colours from the first
    frame, and how the scenes ``m`` cycles to are opened."""
    from livox_viz.widgets.commands import COMMANDS, SCENE_COLOUR_CHOICES, _session
    from livox_viz.widgets.session import SCENE_COLOURS

    from livox_viz.cli import build_parser

    assert SCENE_COLOUR_CHOICES == SCENE_COLOURS
    args = build_parser(COMMANDS).parse_args([
        "render", "--preset", "livox_mid70_risley", "--returns", "datasheet", "--scene-colour", "reflectivity",
        "--reflectance", "0.9", "--up", "y", "--out", str(tmp_path / "r.png")])
    session = _session(args, "render")
    assert session.display.scene_colour == "reflectivity"
    assert session.scene_options == {"up": "y", "reflectance": 0.9}
    session.advance_to(0.1)
    live = session.scene_ring.live_slots()
    np.testing.assert_array_equal(session.scene_ring.scalars[live], session.scene_ring.reflectivity[live])


# Honest drawing, picking, exports (issue 31) ----------------------------------------------------------
def on_screen(renderer, xyz) -> tuple[float, float, float]:
    """Where the display-frame point ``xyz`` (z up) is drawn in ``renderer``: VTK's pixels (origin bottom left) and
    depth."""
    renderer.SetWorldPoint(float(xyz[0]), float(xyz[1]), float(xyz[2]), 1.0)
    renderer.WorldToDisplay()
    return renderer.GetDisplayPoint()


def test_a_scene_pick_returns_the_values_stored_for_the_point_and_two_picks_their_distance(app: LivoxVizApp) -> None:
    from livox_viz.casting.scan import MountedCaster
    from livox_viz.patterns.factory import make_pattern

    session = app.session
    session.advance_to(0.3)
    app.refresh()
    app.render(every=True)
    renderer = app.scene_view.renderer
    ring = session.scene_ring
    # The frames themselves, cast again: what a pick must give back for a point is in their arrays.
    frame = MountedCaster(session.config, session.caster, session.vehicle_pose, None, 0).cast(
        make_pattern(session.config, 0).take(30_000))
    picked = []
    for slot in ring.live_slots()[:: max(1, ring.count // 40)]:
        x, y, _ = on_screen(renderer, ring.positions[slot].astype(float) * [1, -1, -1])  # NED to z up
        width, height = renderer.GetSize()
        if not (5 < x < width - 5 and 5 < y < height - 5):
            continue
        found = app.pick_scene(x, y)
        if found is None:
            continue
        index = int(np.flatnonzero(frame.t == found["t_s"])[0])  # the pulse it came from (one return each)
        assert found["range_m"] == pytest.approx(frame.range_m[index], rel=1e-6)
        np.testing.assert_allclose(found["xyz_sensor"], frame.xyz_decoded[index], atol=1e-5)
        decoded = frame.xyz_decoded[index]
        assert found["azimuth_deg"] == pytest.approx(math.degrees(math.atan2(decoded[1], decoded[0])), abs=1e-4)
        assert found["elevation_deg"] == pytest.approx(
            math.degrees(math.atan2(-decoded[2], math.hypot(decoded[0], decoded[1]))), abs=1e-4)
        assert found["reflectivity"] == frame.reflectivity[index] and found["tag"] == frame.tag[index]
        assert found["return_number"] == frame.return_number[index]
        assert found["frame"] == index // session.config.points_per_frame
        picked.append(found)
        if len(picked) >= 2:
            break
    assert len(picked) == 2
    distance = float(np.linalg.norm(np.subtract(picked[1]["xyz_world"], picked[0]["xyz_world"])))
    assert picked[1]["distance_m"] == pytest.approx(distance) and f"{distance:.3f} m" in app.pick_text
    assert "picks" in app.plotters["scene"].actors
    # A click where no point is picks nothing, and says so.
    session.restart()
    app.refresh()
    assert app.pick_scene(x, y) is None and "no point" in app.pick_text


def test_a_click_picks_a_point_drawn_within_a_few_pixels_or_says_none_is_there(app: LivoxVizApp) -> None:
    """A first-use trial's click on empty sky picked a point 230 px away (VTK's point picker took its tolerance as
    a length at the focal plane), and a click outside the pattern named its nearest sample however far. Over a
    grid of clicks on each view (the scene from behind and from the top), and 3 px beside drawn points: a point
    drawn within the tolerance is picked, as near as the nearest drawn; farther, none is, and the status says so."""
    from livox_viz.widgets.app import PICK_TOLERANCE_PX
    from livox_viz.widgets.views import display_points

    session = app.session
    session.advance_to(0.3)
    app.refresh()
    rng = np.random.default_rng(3)

    def clicks(renderer, drawn: np.ndarray, pick) -> list[bool]:
        width, height = renderer.GetSize()
        grid = [(x, y) for x in range(4, width, 23) for y in range(4, height, 23)]
        beside = [tuple(drawn[k] + (3.0, 0.0)) for k in rng.choice(len(drawn), 10, replace=False)]
        picked = []
        for x, y in grid + beside:
            nearest = np.hypot(*(drawn - (x, y)).T).min()
            found = pick(x, y)
            if nearest > PICK_TOLERANCE_PX + 0.5:
                assert found is None and app.pick_text.startswith("no point under the cursor"), (x, y, nearest)
            elif nearest < PICK_TOLERANCE_PX - 0.5:
                assert found is not None, (x, y, nearest)
            picked.append(found is not None)
        return picked

    for camera in ("behind", "top"):
        app.set_scene_camera(camera)
        app.render(every=True)
        view = app.scene_view
        slots = pv.convert_array(view.poly.GetVerts().GetConnectivityArray())
        points = session.scene_ring.positions[slots].astype(float) * [1, -1, -1]  # NED to the display's z up
        drawn, shown = display_points(view.renderer, points)
        sample = rng.choice(len(points), 50, replace=False)  # where VTK itself draws them
        np.testing.assert_allclose(drawn[sample], [on_screen(view.renderer, points[k])[:2] for k in sample],
                                   atol=1e-6)
        drawn = drawn[shown]

        def pick(x, y, drawn=drawn):
            found = app.pick_scene(x, y)
            if found is not None:  # as near as the nearest drawn point
                here = on_screen(app.scene_view.renderer, np.asarray(found["xyz_world"]) * [1, -1, -1])[:2]
                assert math.hypot(here[0] - x, here[1] - y) <= np.hypot(*(drawn - (x, y)).T).min() + 1.0
            return found

        picked = clicks(view.renderer, drawn, pick)
        assert any(picked) and not all(picked), camera
    ring = session.pattern_ring
    live = ring.positions[ring.live_slots()].astype(float)
    drawn, _ = display_points(app.pattern_view.renderer, np.column_stack([live[:, :2], np.zeros(len(live))]))
    picked = clicks(app.pattern_view.renderer, drawn, app.pick_pattern)
    assert any(picked) and not all(picked)


def test_a_pattern_pick_gives_the_angles_and_time_of_the_nearest_sample(app: LivoxVizApp) -> None:
    session = app.session
    session.advance_to(0.2)
    app.refresh()
    app.render(every=True)
    renderer = app.pattern_view.renderer
    ring = session.pattern_ring
    slot = ring.live_slots()[1234]
    x, y, _ = on_screen(renderer, (ring.positions[slot, 0], ring.positions[slot, 1], 0.0))
    found = app.pick_pattern(x, y)
    xy = ring.positions[ring.live_slots(), :2].astype(float)
    nearest = np.argmin(np.hypot(xy[:, 0] - found["x_deg"], xy[:, 1] - found["y_deg"]))
    assert found["distance_deg"] < 0.5  # within a pixel or two of the sample
    assert found["t_s"] == ring.times[ring.live_slots()[nearest]]
    assert found["t_s"] == pytest.approx(found["index"] / session.config.point_rate)


def pick_points(app: LivoxVizApp, count: int) -> list[dict]:
    """Click ``count`` points of the cloud, each at least 20 px from the ones before (VTK's pixels)."""
    renderer = app.scene_view.renderer
    ring = app.session.scene_ring
    width, height = renderer.GetSize()
    picked, places = [], []
    for slot in ring.live_slots()[:: max(1, ring.count // 400)]:
        x, y, _ = on_screen(renderer, ring.positions[slot].astype(float) * [1, -1, -1])
        if not (5 < x < width - 5 and 5 < y < height - 5) or any(math.hypot(x - a, y - b) < 20 for a, b in places):
            continue
        found = app.pick_scene(x, y)
        if found is not None:
            picked.append(found)
            places.append((x, y))
        if len(picked) == count:
            return picked
    raise AssertionError(f"only {len(picked)} points could be picked")


def haversine_deg(a: dict, b: dict) -> float:
    """The angle between two picks' rays from their azimuths and elevations (the haversine formula)."""
    az_a, el_a, az_b, el_b = (math.radians(p[k]) for p in (a, b) for k in ("azimuth_deg", "elevation_deg"))
    h = math.sin((el_b - el_a) / 2) ** 2 + math.cos(el_a) * math.cos(el_b) * math.sin((az_b - az_a) / 2) ** 2
    return math.degrees(2 * math.asin(math.sqrt(h)))


def test_the_picks_are_any_number_each_marked_with_its_number_and_the_last_ones_measured(app: LivoxVizApp) -> None:
    """Issue 45 item 6: the list held two picks; now every click joins it, each dot numbered in the view, the
    distance and the rays' angle of the last two and the angle at the middle one of the last three said; Remove
    last and Clear take picks and marks away."""
    session = app.session
    session.advance_to(0.3)
    app.refresh()
    app.render(every=True)
    picked = pick_points(app, 4)
    assert app.picks == picked
    actors = app.plotters["scene"].actors
    marks = actors["picks"].mapper.GetInput()
    np.testing.assert_allclose(marks.points, [p["xyz_world"] for p in picked])
    lines = marks.lines
    assert list(lines) == [3, 1, 2, 3]  # the measured segments: 2-3 and 3-4
    numbers = actors["picks-numbers"].GetMapper().GetInputAlgorithm().GetInput()
    labels = numbers.GetPointData().GetAbstractArray("numbers")
    assert [labels.GetValue(k) for k in range(labels.GetNumberOfValues())] == ["1", "2", "3", "4"]
    # Drawn in the display's frame (z up): NED's y and z turned over.
    np.testing.assert_allclose(pv.wrap(numbers).points, np.array([p["xyz_world"] for p in picked]) * [1, -1, -1],
                               atol=1e-5)
    a, b, c = (np.asarray(p["xyz_world"]) for p in picked[1:])
    distance = float(np.linalg.norm(c - b))
    rays = haversine_deg(picked[2], picked[3])
    sides = np.linalg.norm(a - b), np.linalg.norm(c - b), np.linalg.norm(c - a)
    at_b = math.degrees(math.acos((sides[0] ** 2 + sides[1] ** 2 - sides[2] ** 2) / (2 * sides[0] * sides[1])))
    assert picked[3]["distance_m"] == pytest.approx(distance)
    assert app.pick_text.startswith(f"pick 4: range {picked[3]['range_m']:.3f} m")
    assert f"{distance:.3f} m from pick 3, rays {rays:.3f} deg apart" in app.pick_text
    assert f"angle 2-3-4 at pick 3: {at_b:.2f} deg" in app.pick_text

    app.remove_last_pick()
    assert app.picks == picked[:3] and app.plotters["scene"].actors["picks"].mapper.GetInput().n_points == 3
    assert app.pick_text.startswith("pick 3: ") and session.message == "pick 4 removed"
    app.clear_picks()
    assert app.picks == [] and app.pick_text == "" and session.message == "3 picks cleared"
    actors = app.plotters["scene"].actors
    assert "picks" not in actors and "picks-numbers" not in actors
    with pytest.raises(LivoxVizError, match="no pick to remove"):
        app.remove_last_pick()


def test_the_scene_camera_turns_about_the_last_pick_and_r_gives_the_default_back(app: LivoxVizApp) -> None:
    """CloudCompare's Pick rotation center: the focal point goes to the pick, the camera only moved sideways (its
    direction, up and the pick's depth kept), the pick in the middle of the view; r resets."""
    session = app.session
    with pytest.raises(LivoxVizError, match="no pick to turn about"):
        app.turn_about_last_pick()
    session.advance_to(0.3)
    app.refresh()
    app.render(every=True)
    camera = app.scene_view.renderer.camera
    default = np.array(camera.focal_point)
    pick_points(app, 2)
    before = np.array(camera.position), np.array(camera.focal_point), np.array(camera.up)
    direction = (before[1] - before[0]) / np.linalg.norm(before[1] - before[0])
    target = np.asarray(app.picks[-1]["xyz_world"]) * [1, -1, -1]
    app.scene_view.follow = True
    app.turn_about_last_pick()
    assert not app.scene_view.follow and "turns about pick 2" in session.message
    position, focal = np.array(camera.position), np.array(camera.focal_point)
    np.testing.assert_allclose(focal, target, atol=1e-9)
    np.testing.assert_allclose((focal - position) / np.linalg.norm(focal - position), direction, atol=1e-9)
    np.testing.assert_allclose(camera.up, before[2], atol=1e-12)
    assert float(np.dot(position - before[0], direction)) == pytest.approx(0.0, abs=1e-9)  # sideways only
    assert np.linalg.norm(focal - position) == pytest.approx(float(np.dot(target - before[0], direction)))
    width, height = app.scene_view.renderer.GetSize()
    x, y, _ = on_screen(app.scene_view.renderer, target)
    assert (x, y) == (pytest.approx(width / 2, abs=1), pytest.approx(height / 2, abs=1))
    app.reset_cameras()
    np.testing.assert_allclose(camera.focal_point, default, atol=1e-9)


def test_a_fixed_colour_range_spans_the_scene_s_bar_per_colouring_until_automatic(app: LivoxVizApp) -> None:
    """View > Colour range (ParaView's custom range): the scene's colours and bar span the typed range, for the
    colouring it was typed for, the heads-up text says it is fixed; Automatic gives the data's range back; a
    screenshot's sidecar keeps it."""
    session = app.session
    session.advance_to(0.3)
    bar = app.scene_view.scalar_bar
    mapper = app.scene_view.actor.mapper
    app.refresh()
    assert tuple(mapper.scalar_range) == (0.0, 150.0)  # the data's: the range colouring to 150 m
    assert app.set_colour_range("5", "40") == (5.0, 40.0)
    app.refresh()
    assert tuple(mapper.scalar_range) == (5.0, 40.0) and tuple(bar.GetLookupTable().GetRange()) == (5.0, 40.0)
    table = mapper.lookup_table
    assert table.map_value(60.0) == table.map_value(40.0) != table.map_value(39.0)  # clamped above max
    assert "colour: range, fixed 5 to 40 m" in app.hud.scene_state.GetText(2)
    for low, high in (("40", "5"), ("nan", "40"), ("x", "40")):
        with pytest.raises(LivoxVizError, match="allowed"):
            app.set_colour_range(low, high)
    assert session.display.scene_colour_ranges == {"range": (5.0, 40.0)}
    app.set_scene_colour("height")  # its own range: the data's
    app.refresh()
    assert tuple(mapper.scalar_range) == (0.0, 30.0) and "fixed" not in app.hud.scene_state.GetText(2)
    app.set_scene_colour("reflectivity")
    app.set_colour_range("10", "100")
    app.refresh()
    assert tuple(mapper.scalar_range) == (10.0, 100.0)
    table = app.scene_view.actor.mapper.lookup_table
    marks = {table.GetAnnotatedValue(k).ToDouble(): table.GetAnnotation(k)
             for k in range(table.GetNumberOfAnnotatedValues())}
    # The ends, and the bytes that mean something inside (not 1, 150 or 255, which are off the bar).
    assert marks == {10.0: "10", 15.0: "15  10 %", 75.0: "75  50 %", 100.0: "100"}
    state = app.drawing_state()
    json.dumps(state)
    app.set_scene_colour("range")
    app.refresh()
    assert tuple(mapper.scalar_range) == (5.0, 40.0)
    app.automatic_colour_range()
    app.refresh()
    assert tuple(mapper.scalar_range) == (0.0, 150.0) and "fixed" not in app.hud.scene_state.GetText(2)
    session.display.scene_colour_ranges.clear()
    app.apply_drawing_state(json.loads(json.dumps(state)))
    assert session.display.scene_colour_ranges == {"range": (5.0, 40.0), "reflectivity": (10.0, 100.0)}
    with pytest.raises(LivoxVizError, match="min 9 is not below max 1"):
        app.apply_drawing_state({"scene": {"colour_ranges": {"range": [9, 1]}}})


def test_the_windows_cloud_exports_as_scan_writes_it(app: LivoxVizApp, tmp_path: Path) -> None:
    """File > Export: the window's points again, by scan's writers, read back with plyfile."""
    from livox_viz.widgets.files import window_export
    from plyfile import PlyData

    session = app.session
    session.advance_to(0.8)
    written = window_export(session, tmp_path / "window.ply")()
    ring = session.scene_ring
    assert written == ring.count
    vertices = PlyData.read(str(tmp_path / "window.ply"))["vertex"]
    exported = np.column_stack([vertices["x"], vertices["y"], vertices["z"]])
    np.testing.assert_allclose(exported, ring.ordered(ring.positions), atol=2e-3)  # the window's float32 copy
    np.testing.assert_array_equal(vertices["reflectivity"], ring.ordered(ring.reflectivity))


def test_time_bars_show_their_own_start_and_end_with_distinct_marks() -> None:
    from livox_viz.widgets.views import time_marks

    for low, high in ((105.5, 106.0), (0.0, 0.5), (1234.9, 1235.0), (0.0, 10.0), (99.99, 100.0)):
        marks = time_marks(low, high)
        texts = list(marks.values())
        assert min(marks) == low and max(marks) == high
        assert len(set(texts)) == len(texts) >= 2, marks  # the old bar read "106" on every tick
        assert all(float(text) == pytest.approx(value, abs=10 ** -len(text.split(".")[-1]))
                   for value, text in marks.items())


@pytest.mark.parametrize(("mode", "count"), [("petal", 20), ("figure-8", 10), ("flower", 5), ("arc", 4)])
def test_categorical_colourings_get_a_legend_of_categories(app: LivoxVizApp, mode: str, count: int) -> None:
    app.session.advance_to(0.3)
    app.set_pattern_colour(mode)
    app.refresh()
    bar, table = app.pattern_view.scalar_bar, app.pattern_view.actor.mapper.lookup_table
    assert bar.GetDrawAnnotations() and bar.GetNumberOfLabels() == 0
    assert table.n_values == count and table.scalar_range == (-0.5, count - 0.5)
    colours = {tuple(table.values[k]) for k in range(count)}
    assert len(colours) == count  # distinct colours, not a ramp's neighbours
    names = [table.GetAnnotation(k) for k in range(table.GetNumberOfAnnotatedValues())]
    assert names[0] == ("1 UL out" if mode == "arc" else "1") and len(names) <= 12
    assert bar.GetTitle().startswith(mode)  # "figure-8 in flower": what the numbers count
    # The marks stand left of the bar, between it and the pattern: "figure-8 17" ran into both (a first-use trial).
    assert max(len(name) for name in names) <= 8
    values = app.session.pattern_ring.scalars[app.session.pattern_ring.live_slots()]
    assert set(np.unique(values)) <= set(range(count))


def test_the_coverage_of_a_window_drawn_in_part_says_it_is_that_of_the_points_shown(
        app: LivoxVizApp, monkeypatch: pytest.MonkeyPatch) -> None:
    """At 5 M pts/s the same pattern read 98.5 % drawn as points and 100 % as a density image (fewer points
    dropped): a trial took it for the pattern's. Holding fewer than fired, the figure says "of these"."""
    session = app.session
    session.advance_to(0.3)
    assert "coverage of these" not in app.hud.pattern_text(session) and "coverage " in app.hud.pattern_text(session)
    monkeypatch.setattr(session, "points_fired_in_window", lambda: session.pattern_ring.count + 1000)
    assert "coverage of these " in app.hud.pattern_text(session)


def test_reflectivity_under_ideal_returns_says_why_it_is_one_colour(app: LivoxVizApp) -> None:
    app.session.advance_to(0.2)
    app.set_scene_colour("reflectivity")
    app.refresh()
    assert "ideal returns carry no intensity" in app.hud.scene_state.GetText(2)
    app.set_returns_model("datasheet")
    app.refresh()
    assert "no intensity" not in app.hud.scene_state.GetText(2)


def test_skipped_points_and_thinned_clouds_are_said(app: LivoxVizApp) -> None:
    """A tick too far behind skips points: the view says how many of those fired it holds, and why."""
    session = app.session
    session.set_config(session.config.with_param("data_width", 5000), "fast")  # 2 000 000 points/s
    session.advance_to(0.5)
    app.refresh()
    text = app.hud.state.GetText(2)
    assert session.pattern_ring.count == 400_000 and session.points_fired_in_window() == 1_000_000
    assert "400,000 points of 1,000,000 fired (600,000 skipped" in text
    scene = app.hud.scene_state.GetText(2)
    assert f"drawing {app.scene_view.drawn_count():,}" in scene or app.scene_view.stride() == 1
    # The coverage chart says where a curve stops when the point budget ends it before 4 s.
    app.charts.finish()
    assert "(to 1 s" in app.charts.ours_coverage.label


def test_the_panorama_fills_the_view_at_a_readable_height_with_every_mark(urban, tmp_path: Path) -> None:
    session = Session(load_preset("livox_mid360"), urban, seed=0, preset_name="livox_mid360")
    app = LivoxVizApp(session, off_screen=True, window_size=(1600, 900), views="pattern")
    try:
        view = app.pattern_view
        renderer = view.renderer
        x0, x1, y0, y1 = session.config.field_of_view.bounds
        corners = []
        for x, y in ((x0, y0 * view.stretch), (x1, y1 * view.stretch)):
            corners.append(on_screen(renderer, (x, y, 0.0))[:2])
        width, height = renderer.GetSize()
        band_width, band_height = corners[1][0] - corners[0][0], corners[1][1] - corners[0][1]
        assert band_width > 0.6 * width and band_height > 0.3 * height  # it was 50 px of 600
        assert corners[0][0] > 0 and corners[1][0] < 0.85 * width  # whole, clear of the colour bar
        texts = view.guide_labels
        assert {"-180°", "-135°", "-90°", "-45°", "0°", "45°", "90°", "135°", "180°"} <= set(texts)
        assert {"0°", "10°", "20°", "30°", "40°", "50°"} <= set(texts)
        # A click finds true degrees: the stretch is undone.
        session.advance_to(0.1)
        found = session.nearest_pattern_point(*view.plane_point((30.0, 20.0 * view.stretch, 0.0)))
        assert abs(found["y_deg"] - 20.0) < 3.0
    finally:
        app.close()


def test_the_scene_views_text_stays_after_a_scene_change(app: LivoxVizApp) -> None:
    """A first-use trial: after m the scene view's lines (triangles, returns, colouring) were gone for good."""
    from livox_viz.scene.scenes import open_scene

    session = app.session
    session.advance_to(0.3)
    app.refresh()
    renderer, text = app.plotters["scene"].renderer, app.hud.scene_state
    assert renderer.HasViewProp(text)
    for name in ("open_field", "urban"):
        session.set_scene(open_scene(name))
        session.advance_to(session.scan_time + 0.1)
        app.refresh()
        app.render()
        assert renderer.HasViewProp(text) and text.GetVisibility(), name
        assert text.GetText(2).startswith(f"scene {name}:")
        assert len([a for a in renderer.actors.values() if a is app.scene_view.scene_actor]) == 1


@pytest.mark.parametrize("width", [330, 640])
def test_the_panoramas_azimuth_marks_stand_clear_of_each_other_in_a_narrow_view(urban, width: int) -> None:
    """At 1280x720 the pattern view is about 330 pixels wide: "-180°-135°-90°" ran into one another. Where 45
    degrees are too few pixels the marks go every 90 degrees (the lines stay every 45)."""
    session = Session(load_preset("livox_mid360"), urban, seed=0, preset_name="livox_mid360")
    app = LivoxVizApp(session, off_screen=True, window_size=(width, 600), views="pattern")
    try:
        view = app.pattern_view
        marks = sorted({int(t[:-1]) for t in view.guide_labels} & {-180, -135, -90, -45, 0, 45, 90, 135, 180})
        assert {-180, -90, 0, 90, 180} <= set(marks)
        pixels = [on_screen(view.renderer, (azimuth, 0.0, 0.0))[0] for azimuth in marks]
        # "-135°" is about 36 pixels wide at the marks' 12 points.
        assert min(np.diff(pixels)) >= 40, (marks, pixels)
        assert (45 in marks) == (width >= 640)
    finally:
        app.close()


@pytest.mark.parametrize(("size", "every_line"), [((240, 636), False), ((700, 700), True)])
def test_the_panoramas_elevation_marks_stand_clear_of_each_other_in_a_short_band(urban, size, every_line) -> None:
    """In an 1100 px window the Mid-360's band was about 150 pixels wide and 60 tall: "50°40°30°" ran into one
    another (a first-use trial). Where a line's mark would not stand clear, only every 2nd (3rd, ...) is marked."""
    session = Session(load_preset("livox_mid360"), urban, seed=0, preset_name="livox_mid360")
    app = LivoxVizApp(session, off_screen=True, window_size=size, views="pattern")
    try:
        view = app.pattern_view
        labels = view.guide_labels
        marks = [int(t[:-1]) for t in labels[labels.index("180°") + 1:]]  # the azimuths' marks come first
        pixels = [on_screen(view.renderer, (-180.0, elevation * view.stretch, 0.0))[1] for elevation in marks]
        assert len(marks) >= 2 and min(np.diff(pixels)) >= 16, (marks, pixels)
        assert (marks == [0, 10, 20, 30, 40, 50]) == every_line, marks
    finally:
        app.close()


def test_a_wide_reference_fits_the_view_and_stays_behind_our_points(app: LivoxVizApp) -> None:
    from livox_viz.widgets.overlay import PresetSource

    app.set_reference(PresetSource(load_preset("livox_hap"), "livox_hap"))
    app.session.advance_to(1.0)
    app.refresh()
    view = app.pattern_view
    renderer = view.renderer
    r0, r1, s0, s1 = load_preset("livox_hap").field_of_view.bounds
    for x, y in ((r0, s0), (r1, s1)):
        px, py, _ = on_screen(renderer, (x, y, 0.0))
        width, height = renderer.GetSize()
        assert 0 <= px <= width and 0 <= py <= height
    camera_z = renderer.camera.position[2]
    assert view.reference_actor.GetPosition()[2] < view.actor.GetPosition()[2] < camera_z  # ours in front


def test_the_follow_camera_turns_with_the_vehicle_so_the_cloud_stays_in_view(urban) -> None:
    """On a circle the sensor turns: the camera keeps its place in the vehicle's own frame (it used to keep only
    its offset in the world, and the cloud ahead of the sensor left the view)."""
    from livox_viz.widgets.views import _heading

    from livox_viz.motion.flights import builtin_trajectory

    trajectory = builtin_trajectory("circle", 5.0, urban.vehicle_pose, 12.0)
    session = Session(load_preset("livox_mid70"), urban, seed=0, trajectory=trajectory)
    app = LivoxVizApp(session, off_screen=True, window_size=SIZE, views="scene")
    try:
        assert app.scene_view.follow

        def in_vehicle_frame() -> np.ndarray:
            vehicle = session.vehicle_pose_now
            heading = _heading(vehicle.rotation)
            here = vehicle.origin * [1, -1, -1]
            offset = np.array(app.scene_view.renderer.camera.position) - here
            c, s = math.cos(heading), math.sin(heading)
            return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ offset  # undo the turn (display z up)

        session.advance_to(1.0)
        app.refresh()
        start = in_vehicle_frame()
        for t in (3.0, 5.0, 8.0):
            session.advance_to(t)
            app.refresh()
            np.testing.assert_allclose(in_vehicle_frame(), start, atol=1e-6)
        assert abs(_heading(session.vehicle_pose_now.rotation) - _heading(trajectory.pose_at(1.0).rotation)) > 0.5
        # Most of the window's cloud projects inside the view.
        renderer = app.scene_view.renderer
        inside = 0
        ring = session.scene_ring
        slots = ring.live_slots()[:: max(1, ring.count // 200)]
        for slot in slots:
            x, y, z = on_screen(renderer, ring.positions[slot].astype(float) * [1, -1, -1])
            width, height = renderer.GetSize()
            inside += 0 <= x <= width and 0 <= y <= height and 0 <= z <= 1
        assert inside > 0.8 * len(slots)
    finally:
        app.close()


def test_a_window_filled_over_ticks_holds_what_one_filled_at_once_holds(app: LivoxVizApp) -> None:
    """The window fills a new integration window a share per tick (a million points at once held its UI thread for
    seconds): the same points, and the clock does not run meanwhile."""
    session = app.session
    session.advance_to(3.0)
    session.set_window_seconds(2.0)
    whole = session.pattern_ring.ordered(session.pattern_ring.positions).copy()
    session.fill_per_tick = 30_000
    session.set_window_seconds(0.5)
    session.set_window_seconds(2.0)
    ticks = 0
    while session.filling is not None:
        assert 0.0 <= session.filling < 1.0
        session.tick(now=100.0 + ticks)  # a second of wall time a tick: the clock must not move
        ticks += 1
    assert ticks == -(-200_000 // 30_000) - 1 and session.scan_time == pytest.approx(3.0)
    np.testing.assert_array_equal(session.pattern_ring.ordered(session.pattern_ring.positions), whole)


def test_the_views_text_keeps_its_lines_short_so_vtk_does_not_shrink_it(app: LivoxVizApp) -> None:
    """VTK shrinks a corner text to fit its longest line: the unlimited window's note (110 characters) made the
    whole text 6 px tall in a trial. Every line drawn is at most LINE_CHARS long, and nothing is lost."""
    from livox_viz.widgets.hud import LINE_CHARS, wrapped
    from livox_viz.widgets.overlay import WINDOWS

    session = app.session
    session.fill_per_tick = 0
    session.set_window(WINDOWS.index(None))
    session.advance_to(12.0)  # more fired than the unlimited window holds
    app.refresh()
    shown = app.hud.pattern_text(session, app.pattern_view.density_shown())
    for actor, text in ((app.hud.state, shown), (app.hud.scene_state, None)):
        drawn = actor.GetText(2)
        assert max(len(line) for line in drawn.splitlines()) <= LINE_CHARS, drawn
        if text is not None:
            assert "fired" in text and max(len(line) for line in text.splitlines()) > LINE_CHARS  # the long line
            assert " ".join(drawn.split()) == " ".join(text.split())
    assert wrapped("a " * 50).count("\n") == 1 and wrapped("short\nlines") == "short\nlines"
    # A number keeps its unit: "coverage 44.1" and " %" came out on two lines in the README's picture.
    line = wrapped("reference livox_mid70_risley (grey), window 0.5 s: coverage 44.1 %")
    assert "44.1 %" in line and all(part.strip() not in ("%", "s") for part in line.splitlines())
    assert max(len(part) for part in line.splitlines()) <= LINE_CHARS


def test_the_heads_up_field_of_view_is_the_panels_number(app: LivoxVizApp) -> None:
    """The text beside the views read '70.1232' against the box's '70.123', two values to a first-use trial; both
    show the value the scan uses (issue 45: a box showed 180 for a typed 179.9999)."""
    app.on_param("camera_fov", 70.1232)
    assert "FOV 70.1232 deg\n" in app.hud.pattern_text(app.session)
    app.on_param("camera_fov", 179.9999)
    assert "FOV 179.9999 deg\n" in app.hud.pattern_text(app.session)


def test_a_sidecars_background_is_drawn_again_and_a_strange_one_named(app: LivoxVizApp) -> None:
    """A sidecar keeps each view's background: a trial's white screenshot was drawn again dark."""
    state = app.drawing_state()
    state["pattern"]["background"] = "white"
    app.apply_drawing_state(state)
    assert app.pattern_view.background_name == "white" and app.scene_view.background_name == "gradient"
    state["scene"]["background"] = "purple"
    with pytest.raises(LivoxVizError, match=r"scene view's background 'purple'; allowed: dark, gradient, black, white"):
        app.apply_drawing_state(state)


# The scene view's projection and filter (issue 45 item 6) ------------------------------------------------------
def display_pixels(renderer, points_display: np.ndarray) -> np.ndarray:
    """``(n, 2)`` VTK's pixels (origin bottom left) of display-frame points, by the camera's own projection."""
    width, height = renderer.GetSize()
    matrix = renderer.GetActiveCamera().GetCompositeProjectionTransformMatrix(width / height, -1, 1)
    projection = np.array([[matrix.GetElement(i, j) for j in range(4)] for i in range(4)])
    homogeneous = np.column_stack([points_display, np.ones(len(points_display))]) @ projection.T
    return np.column_stack([(homogeneous[:, 0] / homogeneous[:, 3] + 1) / 2 * width,
                            (homogeneous[:, 1] / homogeneous[:, 3] + 1) / 2 * height])


def test_orthographic_keeps_the_size_of_what_is_looked_at_and_r_and_the_presets_fit_the_cloud(
        app: LivoxVizApp) -> None:
    """ParaView's parallel projection: switched, a length on the focal plane is as many pixels as before (VTK's own
    projection says); switched back, the eye is where it was. Orthographic, r and each preset camera keep it and
    draw the sensor and nine tenths of the cloud inside the part of the view the colour bar and the text leave free,
    the cloud filling most of it; the top camera looks straight down (a map); the sidecar says parallel."""
    from livox_viz.widgets.views import CAMERA_PRESETS, NED_TO_DISPLAY, SCALAR_BAR_LEFT, SCENE_TEXT_BAND_PX

    session, view = app.session, app.scene_view
    session.advance_to(0.5)
    app.refresh()
    app.render(every=True)
    renderer, camera = view.renderer, view.renderer.camera
    before = app.cameras()["scene"]
    assert view.projection == "perspective" and not before["parallel"]

    def pixels_of_five_metres() -> float:
        focal = np.array(camera.focal_point)
        across = np.cross(np.array(camera.direction), np.array(camera.up))
        ends = np.stack([focal, focal + 5.0 * across / np.linalg.norm(across)])
        return float(np.linalg.norm(np.diff(display_pixels(renderer, ends), axis=0)))

    seen = pixels_of_five_metres()
    app.toggle_projection()
    assert view.projection == "orthographic" and camera.parallel_projection
    assert pixels_of_five_metres() == pytest.approx(seen, rel=1e-6) and seen > 20
    assert "orthographic" in session.message
    app.toggle_projection()
    assert view.projection == "perspective"
    np.testing.assert_allclose(camera.position, before["position"], atol=1e-9)
    assert pixels_of_five_metres() == pytest.approx(seen, rel=1e-6)

    app.set_projection("orthographic")
    ring = session.scene_ring
    cloud = ring.ordered(ring.positions).astype(float) @ NED_TO_DISPLAY[:3, :3].T
    sensor = NED_TO_DISPLAY[:3, :3] @ session.sensor_pose.origin
    width, height = renderer.GetSize()
    free_x, free_y = SCALAR_BAR_LEFT * width, (1 - SCENE_TEXT_BAND_PX / height) * height
    for reset in ("r", *CAMERA_PRESETS):
        if reset == "r":
            app.reset_cameras()
        else:
            app.set_scene_camera(reset)
        assert view.projection == "orthographic", reset
        x, y = display_pixels(renderer, np.vstack([sensor, cloud])).T
        inside = (x >= 0) & (x <= free_x) & (y >= 0) & (y <= free_y)
        assert inside[0] and inside[1:].mean() > 0.9, (reset, inside[1:].mean())
        # Fitted, not merely inside: the cloud's middle 96 % spans most of the free part one way or the other.
        spread = max(np.ptp(np.percentile(x[1:], [2, 98])) / free_x, np.ptp(np.percentile(y[1:], [2, 98])) / free_y)
        assert spread > 0.6, (reset, spread)
        if reset == "top":
            np.testing.assert_allclose(camera.direction, (0.0, 0.0, -1.0), atol=1e-9)
    assert app.cameras()["scene"]["parallel"] is True


def test_the_filter_draws_only_the_points_inside_its_bounds_says_how_many_it_hides_and_hides_them_from_picks(
        app: LivoxVizApp) -> None:
    """The cells drawn are exactly the live slots whose range is inside the bounds (counted here from the ring's
    ranges), after each tick too; the heads-up text says the bounds and the points hidden of the window's; a click
    on a hidden point does not pick it; the sidecar keeps the filter and Clear draws every point again."""
    from livox_viz.widgets.filters import CloudFilter

    session, view = app.session, app.scene_view
    session.advance_to(0.5)
    app.refresh()
    app.render(every=True)
    ring = session.scene_ring
    low, high = 8.0, 30.0

    def drawn() -> np.ndarray:
        return np.sort(pv.convert_array(view.poly.GetVerts().GetConnectivityArray()))

    def expected() -> np.ndarray:
        live = ring.live_slots()
        ranges = ring.range_m[live].astype(np.float64)
        return np.sort(live[(ranges >= low) & (ranges <= high)])

    # A point the filter will hide, clear of every point it keeps on the screen, answers a click before.
    pixels = display_pixels(view.renderer, ring.positions.astype(float) * [1, -1, -1])
    width, height = view.renderer.GetSize()
    kept = expected()
    hidden = [s for s in np.setdiff1d(ring.live_slots(), kept)[::7]
              if 10 < pixels[s, 0] < width - 10 and 10 < pixels[s, 1] < height - 10
              and np.hypot(*(pixels[kept] - pixels[s]).T).min() > 12]
    assert hidden, "no hidden point stands clear on the screen"
    target = pixels[hidden[0]]
    before = app.pick_scene(*target)
    assert before is not None and not low <= before["range_m"] <= high

    app.set_cloud_filter(CloudFilter(range_min_m=low, range_max_m=high))
    app.refresh()
    assert 0 < kept.size < ring.count and np.array_equal(drawn(), kept)
    line = f"filter: range 8-30 m, {ring.count - kept.size:,} of {ring.count:,} hidden"
    assert line in app.hud.scene_state.GetText(2)
    assert app.pick_scene(*target) is None or low <= app.picks[-1]["range_m"] <= high
    session.advance_to(0.8)  # a tick: the new points filtered too, the old ones gone
    app.refresh()
    assert np.array_equal(drawn(), expected())
    assert f"of {ring.count:,} hidden" in app.hud.scene_state.GetText(2)

    state = json.loads(json.dumps(app.drawing_state()))
    assert state["scene"]["filter"] == {"range_min_m": low, "range_max_m": high, "reflectivity_min": None,
                                        "reflectivity_max": None}
    app.set_cloud_filter(CloudFilter(reflectivity_min=1))  # ideal returns carry 0: every point hidden
    app.refresh()
    assert drawn().size == 0 and f"{ring.count:,} of {ring.count:,} hidden" in app.hud.scene_state.GetText(2)
    app.clear_filters()
    app.refresh()
    assert drawn().size == ring.count and "filter:" not in app.hud.scene_state.GetText(2)
    assert "every point" in session.message
    app.apply_drawing_state(state)  # as render --sidecar does
    app.refresh()
    assert np.array_equal(drawn(), expected())
