"""Undo and redo of the window's configuration (issue 45): the session's history, without a window."""

from __future__ import annotations

import pytest
from livox_viz.widgets.history import ConfigHistory, ConfigState, describe_change
from livox_viz.widgets.session import Session

from livox_viz import load_preset
from livox_viz.scene.scenes import open_scene


@pytest.fixture()
def session() -> Session:
    return Session(load_preset("livox_mid70"), open_scene("open_field"), seed=0, preset_name="livox_mid70")


def test_undo_and_redo_walk_the_parameter_changes_back_and_forth(session: Session) -> None:
    first = session.config.param_value("data_width")
    assert session.set_param("data_width", 116) and session.set_param("data_width", 90)
    assert session.set_param("data_height", 30)
    assert session.undo() and session.config.param_value("data_height") != 30
    assert session.message.startswith("undo: DataHeight ")
    assert session.undo() and session.config.param_value("data_width") == 116
    assert session.message == "undo: DataWidth 116 -> 90"
    assert session.undo() and session.config.param_value("data_width") == first
    assert not session.undo() and session.message == "nothing to undo"
    assert session.redo() and session.config.param_value("data_width") == 116
    assert session.message == "redo: DataWidth 250 -> 116".replace("250", f"{first:g}")
    # A new change forgets what could be redone, as in every editor.
    assert session.set_param("data_width", 40)
    assert not session.redo() and session.message == "nothing to redo"
    assert session.undo() and session.config.param_value("data_width") == 116


def test_an_undone_preset_switch_gives_the_old_preset_back_with_its_reset_values(session: Session) -> None:
    session.set_param("data_width", 116)
    tuned = session.config
    session.set_config(load_preset("livox_avia"), "livox_avia")
    assert session.preset_name == "livox_avia"
    assert session.undo()
    assert session.message == "undo: preset livox_mid70 -> livox_avia"
    assert session.preset_name == "livox_mid70" and session.config == tuned
    # A parameter's reset goes back to the Mid-70 preset's value, not the Avia's.
    assert session.preset_config == load_preset("livox_mid70")
    assert session.redo() and session.preset_name == "livox_avia" and session.preset_config == load_preset("livox_avia")


def test_a_value_refused_or_unchanged_is_no_step(session: Session) -> None:
    value = session.config.param_value("data_width")
    assert not session.set_param("data_width", -5)
    assert session.set_param("data_width", value)  # the same value: the scan is not even restarted
    assert session.history.undo_target() is None


def test_the_history_keeps_its_depth_and_says_what_changed() -> None:
    config = load_preset("livox_mid70")
    history = ConfigHistory(depth=3)
    states = [ConfigState(config.with_param("data_width", 100 + i), "p", config) for i in range(5)]
    for state in states[:-1]:
        history.record(state)
    assert [history.undone(states[-1]) for _ in range(3)] == states[3:0:-1]
    assert history.undo_target() is None
    several = config.with_param("data_width", 7).with_param("data_height", 20).with_param("petal_height", 5)
    several = ConfigState(several.with_param("camera_fov", 30), "p", config)
    text = describe_change(ConfigState(config, "p", config), several)
    assert text == "DataWidth 250 -> 7, DataHeight 40 -> 20, CameraFOV 70.432 -> 30 and 1 more"
    # A parameter of otherParams is named as the panel names it.
    assert describe_change(ConfigState(config, "p", config), ConfigState(config.with_param("petal_height", 5), "p",
                                                                         config)) == "[1] petal height h 2.956 -> 5"
