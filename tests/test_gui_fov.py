"""Issue 18 in the window: the sensor's own field of view in the pattern view, the scene, the counts, the charts."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

pv = pytest.importorskip("pyvista")

from livox_viz.widgets.app import LivoxVizApp  # noqa: E402
from livox_viz.widgets.session import Session  # noqa: E402

from livox_viz import load_preset  # noqa: E402
from livox_viz.cli import main  # noqa: E402
from livox_viz.patterns.metrics import coverage  # noqa: E402
from livox_viz.patterns.planes import xy_from_directions  # noqa: E402
from livox_viz.scene.scenes import open_scene  # noqa: E402


@pytest.fixture(scope="module")
def urban():
    return open_scene("urban")


def make_app(urban, preset: str, tmp_path: Path) -> LivoxVizApp:
    session = Session(load_preset(preset), urban, seed=0, preset_name=preset)
    return LivoxVizApp(session, off_screen=True, window_size=(640, 360), screenshot_dir=tmp_path / "shots")


@pytest.mark.parametrize("preset", ["livox_horizon", "livox_mid360", "livox_avia"])
def test_the_views_draw_the_sensors_own_field_of_view(urban, tmp_path: Path, preset: str) -> None:
    app = make_app(urban, preset, tmp_path)
    try:
        session = app.session
        fov = session.config.field_of_view
        outline = np.asarray(app.pattern_view.renderer.actors["fov-outline"].GetMapper().GetInput().points)[:, :2]
        np.testing.assert_allclose(outline, fov.boundary(), atol=1e-5)
        # The camera holds the whole outline.
        app.pattern_view.reset_camera()
        camera = app.pattern_view.renderer.camera
        x0, x1, y0, y1 = fov.bounds
        width, height = app.pattern_view.renderer.GetSize()
        assert camera.parallel_scale >= (y1 - y0) / 2
        assert camera.parallel_scale * width / height >= (x1 - x0) / 2
        # The scene's wire is the outline's rays: back in the plane, they lie on the outline's edge.
        wire = np.asarray(app.scene_view.renderer.actors["fov-cone"].GetMapper().GetInput().points)
        far = wire[np.linalg.norm(wire, axis=1) > 1.5]
        xy = xy_from_directions(far, fov.plane)
        if fov.plane == "panorama":
            assert set(np.round(xy[:, 1], 3)) >= {round(v, 3) for v in fov.elevation_deg}
            assert np.ptp(xy[:, 0]) > 300  # all the way round
        else:
            from livox_viz.config.fov import _inside_polygon

            grown = fov.boundary() * 1.01
            shrunk = fov.boundary() * 0.99
            assert np.all(_inside_polygon(grown, xy[:, 0], xy[:, 1]))
            assert not np.any(_inside_polygon(shrunk, xy[:, 0], xy[:, 1]))
        # The counts the window keeps are over the field of view's own cells and box.
        session.advance_to(0.3)
        live = session.pattern_ring.ordered(session.pattern_ring.positions)[:, :2].astype(float)
        assert session.visible_coverage() == pytest.approx(coverage(live, fov))
        assert session.density.bounds == pytest.approx(fov.bounds)
        assert session.density.counts.sum() == session.pattern_ring.count
        # The density chart runs along the field of view's own profile.
        charts = app.charts
        assert charts.density.x_label == fov.profile_label
        low, high = fov.profile_range
        half_bin = (high - low) / 60
        x = np.asarray(charts.ours_density.x)
        assert x[0] == pytest.approx(low + half_bin) and x[-1] == pytest.approx(high - half_bin)
    finally:
        app.close()


def test_the_pattern_view_of_each_new_preset_renders(urban, tmp_path: Path) -> None:
    """Every sensor preset draws: points inside the picture, the outline visible, nothing blank."""
    from PIL import Image

    for preset in ("livox_avia", "livox_horizon", "livox_tele15", "livox_hap", "livox_mid360"):
        out = tmp_path / f"{preset}.png"
        assert main(["render", "--preset", preset, "--view", "pattern", "--seconds", "0.3", "--size", "480x360",
                     "--out", str(out)]) == 0
        with Image.open(out) as image:
            pixels = np.asarray(image.convert("RGB")).astype(int)
        background = np.array([16, 20, 28])
        lit = np.abs(pixels - background).sum(axis=2) > 60
        assert 0.05 < lit.mean() < 0.9, f"{preset}: {100 * lit.mean():.1f} % lit"
        yellow = (pixels[..., 0] > 200) & (pixels[..., 1] > 160) & (pixels[..., 2] < 120)
        assert yellow.sum() > 100, f"{preset}: no outline drawn"


def test_info_and_coverage_take_every_sensor_preset(capsys: pytest.CaptureFixture[str]) -> None:
    for preset in ("livox_horizon", "livox_mid360"):
        assert main(["info", "--preset", preset, "--json"]) == 0
        figures = json.loads(capsys.readouterr().out)
        assert figures["pattern_model"] == "track" and figures["lasers"] in (4, 6)
        assert figures["pattern_plane"] == ("panorama" if preset == "livox_mid360" else "boresight")
        assert main(["coverage", "--preset", preset, "--seconds", "0.1", "--json"]) == 0
        fraction = json.loads(capsys.readouterr().out)["coverage"][0]["fraction"]
        config = load_preset(preset)
        from livox_viz.patterns.factory import make_pattern

        xy = make_pattern(config).take(config.point_rate // 10).xy_deg
        assert fraction == pytest.approx(coverage(xy, config.field_of_view))


def test_a_reference_in_another_plane_is_refused_or_removed(urban, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["render", "--reference", "mid360", "--seconds", "0.05", "--size", "200x150", "--out",
                 str(tmp_path / "r.png")]) == 2
    assert "is a panorama pattern" in capsys.readouterr().err
    assert not (tmp_path / "r.png").exists()
    from livox_viz.widgets.overlay import PresetSource

    app = make_app(urban, "livox_horizon", tmp_path)
    try:
        session = app.session
        session.overlay.set_source(PresetSource(load_preset("livox_mid40_risley"), "livox_mid40_risley"), 0.0)
        session.set_config(load_preset("livox_mid360"), "livox_mid360")
        assert session.overlay.source is None and "removed" in session.message
    finally:
        app.close()


def drawn_rect(renderer, bounds: tuple[float, ...]) -> tuple[float, float, float, float]:
    """``(left, right, top, bottom)`` pixels (rows down from the top) of a world box ``(x0, x1, y0, y1, z0, z1)``
    as ``renderer`` draws it."""
    height = renderer.GetSize()[1]
    xs, ys = [], []
    for x in bounds[:2]:
        for y in bounds[2:4]:
            renderer.SetWorldPoint(x, y, 0.0, 1.0)
            renderer.WorldToDisplay()
            px, py, _ = renderer.GetDisplayPoint()
            xs.append(px)
            ys.append(height - py)
    return min(xs), max(xs), min(ys), max(ys)


def lit_rect(view, actor) -> tuple[int, int, int, int]:
    """``(left, right, top, bottom)`` pixels (rows down from the top) of what ``actor`` draws in ``view``: the view
    rendered with nothing else shown, on its plain background."""
    renderer = view.renderer
    props = renderer.GetViewProps()
    everything = [props.GetItemAsObject(k) for k in range(props.GetNumberOfItems())]
    shown = [prop for prop in everything if prop.GetVisibility()]
    try:
        for prop in everything:
            prop.SetVisibility(prop is actor)
        view.plotter.render()
        image = np.asarray(view.plotter.screenshot(return_img=True)).astype(int)
    finally:
        for prop in shown:
            prop.SetVisibility(True)
    rows, cols = np.nonzero(np.abs(image - image[0, 0]).sum(axis=2) > 60)
    assert rows.size, "nothing is drawn"
    return cols.min(), cols.max(), rows.min(), rows.max()


def label_rects(app: LivoxVizApp) -> dict[str, tuple[int, int, int, int]]:
    """The axes' names as drawn: the pattern view rendered with nothing but one name at a time, the box ``(left,
    right, top, bottom)`` of its lit pixels, by the actor's name."""
    names = {name: actor for name, actor in app.pattern_view.plotter.actors.items() if name.startswith("axis-label")}
    assert len(names) == 2
    return {name: lit_rect(app.pattern_view, actor) for name, actor in names.items()}


@pytest.mark.parametrize("size", [(240, 560), (352, 656)])
def test_each_colour_bar_is_whole_in_its_view_and_clear_of_the_pattern(urban, tmp_path: Path, size) -> None:
    """A first-use trial saw the figure-8 legend over the pattern, and the return/tag legend's title cut at the
    view's edge: the bar sat at a share of the width, its words reaching past it. Drawn, each legend (title, strip,
    marks) lies inside its view, and the pattern view's clear of the field of view, for every colouring of the
    rosette and of a panorama, at the pattern view's width in an 1100 and a 1280 window; the scene view's whole
    for every scene colouring at the scene view's narrowest."""
    from livox_viz.widgets.app import offscreen_plotter
    from livox_viz.widgets.session import SCENE_COLOURS, pattern_colours

    for preset in ("livox_mid70", "livox_mid360"):
        session = Session(load_preset(preset), urban, seed=0, preset_name=preset)
        app = LivoxVizApp(session, views="pattern", plotters={"pattern": offscreen_plotter(size)},
                          screenshot_dir=tmp_path / "shots")
        try:
            view = app.pattern_view
            session.advance_to(0.3)
            for mode in (*pattern_colours(session.config), "density"):
                if mode == "density":
                    session.display.drawing = "density"
                else:
                    app.set_pattern_colour(mode)
                app.refresh()
                view.reset_camera()
                left, right, top, bottom = drawn_rect(view.renderer, view.plotter.actors["fov-outline"].GetBounds())
                x0, x1, y0, y1 = lit_rect(view, view.scalar_bar)
                assert 0 < x0 and x1 < size[0] - 1 and 0 < y0 and y1 < size[1] - 1, (preset, mode, (x0, x1, y0, y1))
                assert x0 > right or y1 < top or y0 > bottom, (preset, mode, (x0, x1, y0, y1), (left, right))
        finally:
            app.close()
    session = Session(load_preset("livox_mid70").with_returns_model("datasheet"), urban, seed=0)
    scene_size = (240, size[1])
    app = LivoxVizApp(session, views="scene", plotters={"scene": offscreen_plotter(scene_size)},
                      screenshot_dir=tmp_path / "shots")
    try:
        session.advance_to(0.3)
        app.scene_view.set_background("black")  # plain, for the lit pixels
        for mode in SCENE_COLOURS:
            app.set_scene_colour(mode)
            app.refresh()
            x0, x1, y0, y1 = lit_rect(app.scene_view, app.scene_view.scalar_bar)
            assert 0 < x0 and x1 < scene_size[0] - 1 and 0 < y0 and y1 < scene_size[1] - 1, (mode, (x0, x1))
    finally:
        app.close()


@pytest.mark.parametrize("size", [(352, 656), (496, 836), (900, 480)])
def test_no_axis_name_overlaps_the_pattern_and_each_stays_in_the_view(urban, tmp_path: Path, size,
                                                                       user_presets: Path) -> None:
    """A first-use trial saw the HAP's "x right, deg" drawn over the bottom of its band: the names sat a share of
    the field of view's height away from it, a few pixels for a flat band. Drawn, each name's box lies outside the
    field of view's drawn box and inside the view, for every sensor preset, at the pattern view's sizes in a
    1280x720 and a 1600x900 window and in a wide one."""
    from livox_viz.widgets.app import offscreen_plotter

    from livox_viz import list_presets

    shipped = [info.name for info in list_presets()]
    assert "livox_hap" in shipped and len(shipped) >= 10
    for preset in shipped:
        session = Session(load_preset(preset), urban, seed=0, preset_name=preset)
        app = LivoxVizApp(session, views="pattern", plotters={"pattern": offscreen_plotter(size)},
                          screenshot_dir=tmp_path / "shots")
        try:
            view = app.pattern_view
            view.reset_camera()
            view.refit_guides()
            left, right, top, bottom = drawn_rect(view.renderer, view.plotter.actors["fov-outline"].GetBounds())
            for name, (x0, x1, y0, y1) in label_rects(app).items():
                apart = x1 < left or x0 > right or y1 < top or y0 > bottom
                assert apart, (preset, name, (x0, x1, y0, y1), (left, right, top, bottom))
                assert 0 <= x0 and x1 < size[0] and 0 <= y0 and y1 < size[1], (preset, name, (x0, x1, y0, y1))
        finally:
            app.close()
