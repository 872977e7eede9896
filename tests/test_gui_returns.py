"""The window and the return model: the ideal/datasheet switch, its sliders, colours by reflectivity and tag, noise."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import trimesh

pv = pytest.importorskip("pyvista")

from livox_viz.widgets.app import LivoxVizApp  # noqa: E402
from livox_viz.widgets.controls import RETURN_PARAMS  # noqa: E402
from livox_viz.widgets.session import TAG_CLASSES, Session, tag_classes  # noqa: E402
from livox_viz.widgets.views import REFLECTIVITY_MARKS  # noqa: E402

from livox_viz import PARAM_RANGES, load_preset  # noqa: E402
from livox_viz.casting.returns import RETRO_TOP, reflectivity_byte  # noqa: E402
from livox_viz.config.param_docs import value_bounds  # noqa: E402
from livox_viz.core.poses import Pose  # noqa: E402
from livox_viz.scene.materials import set_face_materials  # noqa: E402
from livox_viz.scene.scenes import Scene, open_scene  # noqa: E402


@pytest.fixture
def app():
    session = Session(load_preset("livox_mid70"), open_scene("urban"), seed=0, preset_name="livox_mid70")
    application = LivoxVizApp(session, off_screen=True, window_size=(640, 360))
    yield application
    application.close()


def test_d_switches_the_return_model_and_t_its_page(app: LivoxVizApp) -> None:
    session = app.session
    assert session.config.returns_model == "ideal"
    session.advance_to(0.2)
    ideal = session.scene_ring.count
    app.toggle_returns_model()
    assert session.config.returns_model == "datasheet" and app.page == "returns"
    assert "returns datasheet" in session.message
    session.advance_to(0.2)
    assert 0 < session.scene_ring.count < ideal  # dark asphalt far along the street drops out
    app.on_param("returns_range_sigma", 0.05)
    assert session.config.return_params.range_sigma_m == ((20.0, 0.05),)
    app.on_param("returns_detection_range_10", 5000.0)  # past the range's end: refused, named
    assert "LivoxVizReturns detection_range_10" in session.message
    app.toggle_slider_page()
    assert app.page == "pattern"
    app.toggle_returns_model()
    assert session.config.returns_model == "ideal" and app.page == "pattern"


def test_return_control_ranges_are_the_validated_ranges() -> None:
    for name in RETURN_PARAMS:
        low, high = value_bounds(name)
        assert PARAM_RANGES[name].contains(low) and PARAM_RANGES[name].contains(high)


def test_scene_colours_by_reflectivity_and_tag(app: LivoxVizApp) -> None:
    session = app.session
    app.toggle_returns_model()
    session.advance_to(0.5)
    ring = session.scene_ring
    live = ring.live_slots()
    assert (ring.reflectivity[live] >= 151).any() and ((ring.tag[live] & 0x03) != 0).any()
    while session.display.scene_colour != "reflectivity":
        app.cycle_scene_colour()
    np.testing.assert_array_equal(ring.scalars[live], ring.reflectivity[live].astype(np.float32))
    app.refresh()
    bar = app.scene_view.scalar_bar
    assert bar.GetDrawAnnotations() and bar.GetNumberOfLabels() == 0
    # The bar's marks are the bytes the model gives a 10 %, 50 % and white target, and the retroreflective top.
    marks = {round(value): text for value, text in REFLECTIVITY_MARKS.items()}
    for reflectance, label in ((0.1, "10 %"), (0.5, "50 %"), (1.0, "white")):
        assert label in marks[int(reflectivity_byte(np.array([reflectance]))[0])]
    assert "retro" in marks[int(reflectivity_byte(np.array([RETRO_TOP]))[0])]
    app.cycle_scene_colour()
    assert session.display.scene_colour == "return/tag"
    np.testing.assert_array_equal(ring.scalars[live], tag_classes(ring.tag[live]))
    app.refresh()
    table = app.scene_view.actor.mapper.lookup_table
    assert table.n_values == len(TAG_CLASSES) and app.scene_view.scalar_bar.GetDrawAnnotations()
    # Tags by hand: return 2 clean, a mixed first return, a false alarm, a near first return (return 0).
    assert tag_classes(np.array([0x20, 0x11, 0x15, 0x00], np.uint8)).tolist() == [2.0, 4.0, 5.0, 0.0]


def test_noise_shows_when_zooming_into_a_wall() -> None:
    wall = trimesh.creation.box((0.5, 60, 60), trimesh.transformations.translation_matrix((20.25, 0, -5)))
    faces = len(wall.faces)
    set_face_materials(wall, np.full(faces, 0.5), np.ones(faces), np.zeros(faces))
    config = replace(load_preset("livox_mid40_risley"), sensor_pos_xyz=(0.0, 0.0, 0.0))
    spread = {}
    for model in ("ideal", "datasheet"):
        session = Session(config.with_returns_model(model), Scene("wall", wall, Pose()), seed=1)
        session.advance_to(0.3)
        x = session.scene_ring.ordered(session.scene_ring.positions)[:, 0]
        spread[model] = float(np.std(x))
    # The decoded points in the window: a flat wall at x = 20 m (one int16 level) without noise, the sheet's
    # 2 cm (and the int16 step's uniform error over the levels it spreads across) with it.
    step = config.range_step
    assert spread["ideal"] < 1e-3
    assert spread["datasheet"] == pytest.approx(np.sqrt(0.02**2 + step**2 / 12), rel=0.10)
