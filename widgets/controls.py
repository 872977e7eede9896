"""The sliders under the views: one per tunable parameter, plus playback speed and the integration window.

Each pattern model has its own set of parameter sliders, drawn in the same
place; only the set of the model in use is shown, or, on the returns page
(key ``t``, and whenever ``d`` turns the datasheet model on), the return
model's sliders: range noise (1 sigma at the sheet's first range), detection
range at 10 % reflectivity, blind zone, beam divergence, false alarms and
angular noise (1 sigma). A slider shows the value in
the user's unit (speed in x real time, the window in seconds), never an
internal index or logarithm.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pyvista as pv

from livox_viz.config.sensor import PARAM_RANGES, SensorConfig

from .overlay import WINDOWS, window_label
from .playback import SPEED_RANGE

#: Sliders under the pattern view, per pattern model: (parameter, short title).
PATTERN_SLIDERS: dict[str, tuple[tuple[str, str], ...]] = {
    "rflysim": (
        ("camera_fov", "FOV, deg"),
        ("petal_height", "[1] petal h, deg"),
        ("spacing_exponent", "[2] spacing p"),
        ("tip_exponent", "[3] tip q"),
        ("figure8_per_flower", "[4] figure-8s/flower"),
        ("flowers_per_figure", "[5] flowers/figure"),
        ("jitter_max_deg", "[6] jitter, deg"),
        ("range_max", "[0] range, m"),
    ),
    "risley": (
        ("prism_rpm_a", "prism A, rpm"),
        ("prism_rpm_b", "prism B, rpm"),
        ("deflection_a", "deflection A, deg"),
        ("deflection_b", "deflection B, deg"),
        ("laser_spacing", "lasers' spacing, x"),
        ("camera_fov", "FOV, deg"),
        ("range_max", "[0] range, m"),
    ),
    "track": (
        ("base_rpm_a", "base A, rpm"),
        ("base_rpm_b", "base B, rpm"),
        ("range_max", "[0] range, m"),
    ),
}
#: The return model's sliders (the returns page, drawn where the pattern's are).
RETURN_SLIDERS: tuple[tuple[str, str], ...] = (
    ("returns_range_sigma", "range noise, m"),
    ("returns_detection_range_10", "range at 10 %, m"),
    ("returns_blind_zone", "blind zone, m"),
    ("returns_false_alarm_rate", "false alarms / pulse"),
    ("returns_divergence_h", "divergence H, deg"),
    ("returns_divergence_v", "divergence V, deg"),
    ("returns_angular_sigma", "angle noise, deg"),
)
SLIDER_PAGES: tuple[str, ...] = ("pattern", "returns")
#: Sliders under the scene view: the frame structure, which sets the point rate W x H x F.
SENSOR_SLIDERS: tuple[tuple[str, str], ...] = (
    ("data_width", "DataWidth W"),
    ("data_height", "DataHeight H"),
    ("data_check_freq", "DataCheckFreq F, Hz"),
)
_STYLE: dict[str, Any] = dict(title_height=0.1, title_color="#dde3ea", color="#dde3ea", slider_width=0.04,
                              tube_width=0.008)


def slider_range(name: str) -> tuple[float, float]:
    """The slider's ends: the validated range, open ends nudged inside."""
    spec = PARAM_RANGES[name]
    nudge = 1 if spec.integer else max((spec.high - spec.low) * 1e-3, 1e-3)
    low = spec.low + nudge if spec.low_open else spec.low
    high = spec.high - nudge if spec.high_open else spec.high
    return float(low), float(high)


class Sliders:
    """All sliders of the window.

    Parameters
    ----------
    plotter : pyvista.Plotter
        With the slider panes at subplots (1, 0), (1, 1) and (1, 2).
    config : SensorConfig
        Their first values.
    on_param : callable
        ``on_param(name, value)`` when a parameter slider is released.
    on_speed, on_window : callable
        ``on_speed(x)`` with the speed in x real time; ``on_window(index)`` into :data:`WINDOWS`.
    speed : float
    window_index : int
    """

    def __init__(self, plotter: pv.Plotter, config: SensorConfig, on_param: Callable[[str, float], None],
                 on_speed: Callable[[float], None], on_window: Callable[[int], None], speed: float,
                 window_index: int) -> None:
        self.plotter = plotter
        self.widgets: dict[str, Any] = {}
        self._model_widgets: dict[str, dict[str, Any]] = {}
        plotter.subplot(1, 0)
        plotter.set_background("#0c0f15")
        #: Which set the left pane shows: the pattern model's sliders or the return model's.
        self.page = "pattern"
        for model, rows in (*PATTERN_SLIDERS.items(), ("returns", RETURN_SLIDERS)):
            made = {}
            for k, (name, title) in enumerate(rows):
                row, col = divmod(k, 4)
                x0 = 0.03 + col * 0.245
                y = 0.68 - row * 0.45
                made[name] = self._param_slider(name, title, config, (x0, y), (x0 + 0.2, y), on_param)
            self._model_widgets[model] = made
        plotter.subplot(1, 1)
        plotter.set_background("#0c0f15")
        for k, (name, title) in enumerate(SENSOR_SLIDERS):
            row, col = divmod(k, 2)
            x0 = 0.05 + col * 0.5
            y = 0.68 - row * 0.45
            self.widgets[name] = self._param_slider(name, title, config, (x0, y), (x0 + 0.4, y), on_param)
        plotter.subplot(1, 2)
        plotter.set_background("#0c0f15")
        # Speed moves on a log scale and the window over a list: the label shows the value, not the position.
        self.widgets["speed"] = plotter.add_slider_widget(
            lambda value: on_speed(10.0**value), rng=[math.log10(SPEED_RANGE[0]), math.log10(SPEED_RANGE[1])],
            value=math.log10(speed), title="speed", pointa=(0.05, 0.68), pointb=(0.45, 0.68),
            interaction_event="always", **_STYLE,
        )
        self.widgets["window"] = plotter.add_slider_widget(
            lambda value: on_window(round(min(max(value, 0), len(WINDOWS) - 1))), rng=[0, len(WINDOWS) - 1],
            value=window_index, title="window", pointa=(0.55, 0.68), pointb=(0.95, 0.68),
            interaction_event="end", **_STYLE,
        )
        for name in ("speed", "window"):
            self.widgets[name].GetRepresentation().ShowSliderLabelOff()
        for widget in self._all():
            widget.GetRepresentation().SetLabelHeight(0.09)
        self.show_model(config.pattern_model)

    def _param_slider(self, name: str, title: str, config: SensorConfig, a: tuple[float, float],
                      b: tuple[float, float], on_param: Callable[[str, float], None]) -> Any:
        spec = PARAM_RANGES[name]
        value = config.param_value(name) if name in _available(config) else slider_range(name)[0]
        return self.plotter.add_slider_widget(
            lambda v, _name=name: on_param(_name, v), rng=list(slider_range(name)), value=value, title=title,
            pointa=a, pointb=b, interaction_event="end", fmt="%.0f" if spec.integer else "%.4g", **_STYLE,
        )

    def _all(self) -> list[Any]:
        return [*self.widgets.values(), *(w for made in self._model_widgets.values() for w in made.values())]

    def show_model(self, model: str) -> None:
        """Show the parameter sliders of ``model`` only (the return model's on the returns page)."""
        shown = "returns" if self.page == "returns" else model
        for name, made in self._model_widgets.items():
            for widget in made.values():
                widget.SetEnabled(name == shown)

    def param_widgets(self) -> dict[str, Any]:
        """The parameter sliders in use (the shown set's and the frame structure's), by parameter."""
        shown = next((m for m, made in self._model_widgets.items()
                      if any(w.GetEnabled() for w in made.values())), "rflysim")
        return {**self._model_widgets[shown], **{n: self.widgets[n] for n, _ in SENSOR_SLIDERS}}

    def set_value(self, name: str, value: float) -> None:
        """Move a slider without calling back."""
        widget = self.param_widgets().get(name) or self.widgets.get(name)
        if widget is not None:
            widget.GetRepresentation().SetValue(value)

    def value(self, name: str) -> float:
        """Where a slider stands."""
        widget = self.param_widgets().get(name) or self.widgets[name]
        return float(widget.GetRepresentation().GetValue())

    def sync(self, config: SensorConfig, speed: float, window_index: int) -> None:
        """Every slider to the configuration's values; titles to the speed and window in their units."""
        self.show_model(config.pattern_model)
        for name, widget in self.param_widgets().items():
            widget.GetRepresentation().SetValue(config.param_value(name))
        self.widgets["speed"].GetRepresentation().SetValue(math.log10(speed))
        self.widgets["window"].GetRepresentation().SetValue(window_index)
        self.show_playback(speed, window_index)

    def show_playback(self, speed: float, window_index: int) -> None:
        """The speed and window sliders' titles carry their values."""
        self.widgets["speed"].GetRepresentation().SetTitleText(f"speed {speed:.3g}x")
        self.widgets["window"].GetRepresentation().SetTitleText(f"window {window_label(WINDOWS[window_index])}")


def _available(config: SensorConfig) -> set[str]:
    """The parameters ``config`` has values for (Risley ones need Risley parameters)."""
    names = set(PARAM_RANGES)
    if config.risley is None:
        names -= {name for name, _ in PATTERN_SLIDERS["risley"]} - {"camera_fov", "range_max"}
    if config.track is None:
        names -= {name for name, _ in PATTERN_SLIDERS["track"]} - {"range_max"}
    return names
