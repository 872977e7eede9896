"""The window's fast paths (issue 19) show what the plain ones did: ring slices, colours, the thinned cloud, the
guides, the screenshot written behind the key, the curves' cells. Off-screen, small windows; no timing here."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from livox_viz.widgets import views  # noqa: E402
from livox_viz.widgets.app import LivoxVizApp  # noqa: E402
from livox_viz.widgets.overlay import WINDOWS  # noqa: E402
from livox_viz.widgets.ring import PointRing  # noqa: E402
from livox_viz.widgets.session import Session  # noqa: E402

from livox_viz import load_preset  # noqa: E402
from livox_viz.motion.flights import builtin_trajectory  # noqa: E402
from livox_viz.patterns.metrics import LIVOX_CELL_DEG, CoverageGrid  # noqa: E402
from livox_viz.scene.scenes import open_scene  # noqa: E402

SIZE = (480, 300)


@pytest.fixture(scope="module")
def urban():
    return open_scene("urban")


@pytest.fixture
def app(urban, tmp_path: Path):
    session = Session(load_preset("livox_mid70"), urban, seed=0, preset_name="livox_mid70")
    application = LivoxVizApp(session, off_screen=True, window_size=SIZE, screenshot_dir=tmp_path / "shots")
    yield application
    application.close()


def test_live_pieces_are_the_live_slots_in_order() -> None:
    ring = PointRing(10)
    for size in (3, 4, 6, 2, 9, 1):
        ring.write(np.zeros((size, 3)), np.zeros(size), np.arange(size, dtype=float), np.arange(size))
        if size == 2:
            ring.drop_older_than(1.0)
        joined = np.concatenate([np.arange(10)[piece] for piece in ring.live_pieces()] or [np.zeros(0, int)])
        np.testing.assert_array_equal(joined, ring.live_slots())


def test_colour_keys_give_the_scalars_of_each_point_as_written(app: LivoxVizApp) -> None:
    session = app.session
    session.set_window(WINDOWS.index(0.1))
    scene = session.scene_ring
    for step in range(1, 40):  # tick by tick until the ring has turned: its live slots wrap around the end
        session.advance_to(0.033 * step)
        if scene.tail + scene.count > scene.capacity:
            break
    assert scene.tail + scene.count > scene.capacity
    seen = set()
    for _ in range(5):
        app.cycle_scene_colour()
        live = scene.live_slots()
        world = scene.positions[live].astype(np.float64)
        mode = session.display.scene_colour
        seen.add(mode)
        # A Livox tag: return number in bits 4-5, spatial noise in 0-1 (mixed), intensity noise in 2-3 (noise).
        by_tag = [5 if tag & 0x0C else 4 if tag & 0x03 else (tag >> 4) & 3 for tag in scene.tag[live].tolist()]
        expected = {"range": np.linalg.norm(world - session.sensor_pose.origin, axis=1),
                    "height": -world[:, 2], "time": scene.times[live],
                    "reflectivity": scene.reflectivity[live].astype(np.float64),
                    "return/tag": np.array(by_tag, dtype=np.float64)}[mode]
        np.testing.assert_allclose(scene.scalars[live], expected, rtol=2e-6, atol=2e-5)
    assert seen == {"range", "height", "time", "reflectivity", "return/tag"}
    app.cycle_pattern_colour()
    ring = session.pattern_ring
    live = ring.live_slots()
    np.testing.assert_array_equal(ring.scalars[live],
                                  session.pattern_scalars(ring.stream_index[live], ring.times[live]))


def test_a_large_cloud_is_drawn_thinned_and_every_point_on_request(app: LivoxVizApp, monkeypatch) -> None:
    session = app.session
    monkeypatch.setattr(views, "SCENE_DRAW_LIMIT", 2000)  # the half-second window holds 50 000 slots
    session.advance_to(0.8)
    app.refresh()
    ring = session.scene_ring
    stride = app.scene_view.stride()
    assert stride == math.ceil(ring.capacity / 2000) > 1
    drawn = app.scene_view.poly.GetVerts()
    slots = pv.convert_array(drawn.GetConnectivityArray())
    assert len(slots) == len(range(0, ring.count, stride)) or abs(len(slots) - ring.count / stride) <= 1
    assert set(slots.tolist()) <= set(ring.live_slots().tolist()) and np.all(slots % stride == 0)
    first = set(slots.tolist())
    session.advance_to(0.85)  # the ring turns: the drawn slots stay the multiples of the stride
    app.refresh()
    assert np.all(pv.convert_array(app.scene_view.poly.GetVerts().GetConnectivityArray()) % stride == 0)
    assert first  # something was drawn
    while session.display.drawing != "points":
        app.cycle_drawing()
    app.refresh()
    assert app.scene_view.poly.n_cells == ring.count


def test_guides_follow_the_fov(app: LivoxVizApp) -> None:
    """The grid and the outline stay two actors, handed new meshes when the FOV changes; the wire follows."""
    actors = app.plotters["pattern"].actors
    grid_actor, outline_actor = actors["grid"], actors["fov-outline"]
    app.on_param("camera_fov", 40.0)
    assert actors["grid"] is grid_actor and actors["fov-outline"] is outline_actor
    outline = np.asarray(outline_actor.mapper.GetInput().points)
    np.testing.assert_allclose(np.hypot(outline[:, 0], outline[:, 1]), 20.0, rtol=1e-9)
    grid = np.asarray(grid_actor.mapper.GetInput().points)
    radii = np.unique(np.round(np.hypot(grid[:, 0], grid[:, 1]), 6))
    assert 10.0 in radii and 20.0 in radii  # the 10-degree ring and the cross hairs' ends
    wire = app.plotters["scene"].actors["fov-cone"].mapper.GetInput()
    rim = np.asarray(wire.points)
    off_axis = rim[np.linalg.norm(rim, axis=1) > 1.0]  # the rim at 1.6 m (the apex is at 0)
    np.testing.assert_allclose(np.hypot(off_axis[:, 1], off_axis[:, 2]) / off_axis[:, 0],
                               math.tan(math.radians(20.0)), rtol=1e-6)  # pv.Line ends are float32
    apex = np.flatnonzero(np.linalg.norm(rim, axis=1) < 1e-12)
    segments = pv.convert_array(wire.GetLines().GetConnectivityArray()).reshape(-1, 2)
    assert np.isin(segments, apex).any(axis=1).sum() == 8  # eight rays from the apex, the rest the rim


def test_the_screenshot_key_writes_behind_and_close_waits(app: LivoxVizApp, tmp_path: Path) -> None:
    from PIL import Image

    app.session.advance_to(0.2)
    app.refresh()
    path = app.take_screenshot()
    assert app.session.message.startswith(("saving", "saved"))
    app.close()  # waits for the writer
    with Image.open(path) as image:
        assert image.size == SIZE
    assert json.loads(path.with_suffix(".json").read_text())["scan_time_s"] == pytest.approx(0.2)
    assert app.session.message == f"saved {path}"


def test_the_cloud_frame_key_recasts_only_for_a_moving_sensor(urban) -> None:
    still = Session(load_preset("livox_mid70"), urban, seed=0)
    app = LivoxVizApp(still, off_screen=True, window_size=SIZE, views="scene")
    try:
        still.advance_to(0.3)
        before = still.scene_ring.positions.copy()
        app.toggle_cloud_frame()
        # A sensor that stays: the two frames are one, so w says so (it said nothing) and casts nothing again.
        assert "does not move" in still.message and still.display.cloud_frame == "world"
        assert still.scene_ring.count > 0
        np.testing.assert_array_equal(still.scene_ring.positions, before)
    finally:
        app.close()
    flight = builtin_trajectory("circle", 5.0, urban.vehicle_pose, 5.0)
    moving = Session(load_preset("livox_mid70"), urban, seed=0, trajectory=flight)
    app = LivoxVizApp(moving, off_screen=True, window_size=SIZE, views="scene")
    try:
        moving.advance_to(0.3)
        world = moving.scene_ring.ordered(moving.scene_ring.positions).copy()
        app.toggle_cloud_frame()
        sensor = moving.scene_ring.ordered(moving.scene_ring.positions)
        assert world.shape == sensor.shape and not np.array_equal(world, sensor)
    finally:
        app.close()


def plain_cell_index(grid: CoverageGrid, xy: np.ndarray) -> np.ndarray:
    """The cell of each point the obvious way, point by point (the reference for the block version)."""
    x0, nx, y0, ny, cell_x, cell_y = grid._axes
    out = np.full(xy.shape[0], -1, dtype=np.int64)
    for k, (x, y) in enumerate(xy):
        column, row = (x - x0) * (1.0 / cell_x), (y - y0) * (1.0 / cell_y)
        if not (0 <= column < nx and 0 <= row < ny):  # NaN fails too
            continue
        i, j = math.floor(column), math.floor(row)
        if grid.inside_mask[i, j]:
            out[k] = i * ny + j
    return out


def test_cells_of_points_in_blocks_match_the_plain_rule() -> None:
    grid = CoverageGrid(35.2, LIVOX_CELL_DEG)
    rng = np.random.default_rng(8)
    xy = rng.uniform(-40, 40, size=(70_000, 2))  # more than one block, some outside the FOV and the grid
    xy[:5] = [[np.nan, 0.0], [0.0, np.inf], [-1e9, 3.0], [0.0, 0.0], [-35.2, 0.0]]
    picked = np.r_[0:5, rng.choice(70_000, 3000, replace=False)]
    np.testing.assert_array_equal(grid.cell_index(xy)[picked], plain_cell_index(grid, xy[picked]))


def test_a_screenshot_is_named_by_its_whole_path(app: LivoxVizApp, tmp_path: Path,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """The default folder is relative (screenshots/): "saved screenshots/..." told a user who started the window
    from a shortcut nothing of where the picture went."""
    monkeypatch.chdir(tmp_path)
    app.screenshot_dir = Path("shots")
    path = app.take_screenshot()
    app.close()
    assert path.is_absolute() and path.parent == tmp_path / "shots" and path.is_file()
    assert app.session.message == f"saved {path}"



def fake_loader_child(monkeypatch: pytest.MonkeyPatch, output: Callable[[], Iterable[str]]) -> None:
    """The loops' loader's child replaced by one whose output is ``output()``, and loading a stage by nothing."""
    import io

    from livox_viz.widgets import warmup

    class Child:
        def __init__(self, *args, **kwargs) -> None:
            self.stdout = output()

        def wait(self) -> int:
            return 0

        def poll(self) -> int:
            return 0

    monkeypatch.setattr(warmup, "warm", lambda stage: None)
    monkeypatch.setattr(warmup.subprocess, "Popen", Child)
    monkeypatch.setattr(warmup.tempfile, "TemporaryFile", lambda: io.BytesIO())


def test_the_background_stages_are_timed_each_from_its_own_start(monkeypatch: pytest.MonkeyPatch) -> None:
    """The child compiles the later stages one after another; each was timed from the first one's start, so a
    first-use trial read "preparing the motion loops, 57 s" (the datasheet's minute), then "..., 0 s"."""
    import threading
    import time

    from livox_viz.widgets import warmup

    datasheet_done = threading.Event()
    said: list[str] = []

    def lines() -> Iterator[str]:
        time.sleep(1.5)  # the datasheet loops compile
        yield "ready datasheet\n"
        datasheet_done.wait(10)
        time.sleep(0.3)
        yield "ready motion\n"

    fake_loader_child(monkeypatch, lines)
    warmer = warmup.LoopWarmer(now=(), later=("datasheet", "motion")).start()
    deadline = time.monotonic() + 10
    while "datasheet" not in warmer.ready and time.monotonic() < deadline:
        time.sleep(0.02)
    said.append(warmer.describe())
    datasheet_done.set()
    assert warmer.wait({"datasheet", "motion"}, timeout=10)
    assert said[0].startswith("preparing the motion loops, 0 s"), said


def test_the_background_childs_pipe_is_closed_when_it_ends(monkeypatch: pytest.MonkeyPatch) -> None:
    """The loader's child's output pipe is closed by the loader, not left to the collector: an unclosed pipe's
    ResourceWarning surfaced whenever a later collection ran (CI blamed an unrelated test for one)."""
    import io

    from livox_viz.widgets import warmup

    closed: list[bool] = []

    class Pipe(io.StringIO):
        def close(self) -> None:
            closed.append(True)
            super().close()

    fake_loader_child(monkeypatch, lambda: Pipe("ready datasheet\n"))
    warmer = warmup.LoopWarmer(now=(), later=("datasheet",)).start()
    assert warmer.wait({"datasheet"}, timeout=10)
    warmer._thread.join(10)
    assert closed == [True]
