"""What each tunable parameter means, in words and units: the table a parameter panel is built from.

:data:`~livox_viz.config.sensor.PARAM_RANGES` holds each parameter's allowed
interval (the one the command line validates); this module adds what a user
needs to tune it: a short title, the unit, a step and a fine step, how many
decimals to show, whether its slider moves on a log scale, and a sentence or
two on what it does to the scan (from ``scan-model.md`` and ``risley.md``).
Nothing here draws: a window builds its controls from :func:`param_doc`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from livox_viz.config.sensor import PARAM_RANGES, ParamRange


@dataclass(frozen=True)
class ParamDoc:
    """One tunable parameter as a user meets it.

    Parameters
    ----------
    title : str
        Short name with its RflySim field, e.g. ``"[3] tip exponent q"``.
    unit : str
        Shown after the value (``""`` for a pure number).
    help : str
        What it does to the scan, in words.
    step : float
        One arrow-key or wheel step of the value; :attr:`fine_step` with Shift or Ctrl held.
    decimals : int
        Decimals shown.
    log : bool
        Whether the slider moves on a log scale (parameters spanning decades).
    """

    title: str
    unit: str
    help: str
    step: float
    decimals: int
    log: bool = False

    @property
    def fine_step(self) -> float:
        """A tenth of :attr:`step` (at least one unit of the last decimal shown)."""
        return max(self.step / 10.0, 10.0 ** -self.decimals)


_DOCS: dict[str, ParamDoc] = {
    "data_width": ParamDoc(
        "DataWidth W", "pts", "Points on one arc (half a petal). The point rate is W x H x F; a larger W draws "
        "each petal with more, closer points and slows the pattern's progress per point.", 1, 0),
    "data_height": ParamDoc(
        "DataHeight H", "arcs", "Arcs per published frame: a frame holds W x H points. With the defaults a frame is "
        "exactly one flower.", 1, 0),
    "data_check_freq": ParamDoc(
        "DataCheckFreq F", "Hz", "Frames per second. The point rate is W x H x F (default 250 x 40 x 10 = 100 000 "
        "points/s).", 1, 0),
    "camera_fov": ParamDoc(
        "CameraFOV", "deg", "Full field of view: twice the length of one petal (tip to tip of a figure-8). The "
        "pattern fills a circle of half this angle.", 0.5, 3),
    "range_max": ParamDoc(
        "[0] max range", "m", "Maximum range, and the int16 scale of the published points: a client decodes "
        "x = x_int / 32767 x range, so a smaller range gives finer steps (range / 65534).", 10, 2, log=True),
    "petal_height": ParamDoc(
        "[1] petal height h", "deg", "Petal height h: how far each of a petal's two arcs rises from the petal's "
        "axis at its middle, half the petal's width (a petal is 2h across). Higher petals cover the gaps between "
        "neighbouring petals sooner; too high and petals overlap.", 0.1, 3),
    "spacing_exponent": ParamDoc(
        "[2] spacing exponent p", "", "How points are spaced along an arc (sample i at -(i/W)^p): 1 spaces them "
        "evenly; above 1 packs them at the pattern's centre and at the petal's tip and thins the middle of the "
        "arc; below 1 does the opposite.", 0.05, 3),
    "tip_exponent": ParamDoc(
        "[3] tip exponent q", "", "Calibration exponent of the outer (tip-side) half of each arc (|cos|^q, "
        "|sin|^q): above 1 the tip grows sharper and the petal's outer half narrower; below 1 blunter and rounder.",
        0.05, 3),
    "figure8_per_flower": ParamDoc(
        "[4] figure-8s per flower N8", "", "Figure-8s in one flower: 2 x N8 petals, 180/N8 degrees apart, "
        "scanned in a random order.", 1, 0),
    "flowers_per_figure": ParamDoc(
        "[5] flowers per figure Nf", "", "Flowers in one figure (pattern), each turned by (180/N8)/Nf degrees "
        "from the last, so the figure fills the gaps between one flower's petals.", 1, 0),
    "jitter_max_deg": ParamDoc(
        "[6] random rotation", "deg", "Largest random rotation added to the running offset after each flower "
        "(or figure: the jitter scope), so successive figures never coincide and coverage keeps growing; 0 "
        "repeats the same figure.", 0.1, 3),
    "prism_rpm_a": ParamDoc(
        "prism A speed", "rpm", "Speed of the first prism (negative: turning the other way). The ratio of the two "
        "speeds sets the pattern's petal count and how fast it fills.", 10, 1),
    "prism_rpm_b": ParamDoc(
        "prism B speed", "rpm", "Speed of the second prism (negative: turning the other way).", 10, 1),
    "deflection_a": ParamDoc(
        "prism A deflection", "deg", "How far the first prism bends the beam: with the second, it sets the "
        "pattern's radius (the field of view is about the sum of the two).", 0.1, 3),
    "deflection_b": ParamDoc(
        "prism B deflection", "deg", "How far the second prism bends the beam (the inner loops' size).", 0.1, 3),
    "laser_spacing": ParamDoc(
        "lasers' spacing", "x", "How far apart the head's lasers point, as a multiple of the fitted spacing "
        "(1 = the real sensor's; 0 puts every laser on one track).", 0.05, 3),
    "base_rpm_a": ParamDoc(
        "base speed A", "rpm", "The first of the track's two steady rates (a turning or swinging part). Every "
        "term of the series turns at a whole multiple of the two.", 10, 1),
    "base_rpm_b": ParamDoc(
        "base speed B", "rpm", "The second of the track's two steady rates.", 10, 1),
    "returns_range_sigma": ParamDoc(
        "range noise", "m", "1-sigma range noise at the sheet's first range (the whole noise table scales with "
        "it): a wall seen edge-on grows this thick.", 0.001, 4, log=True),
    "returns_detection_range_10": ParamDoc(
        "range at 10 %", "m", "Detection range of a 10 %-reflective target (the whole detection table scales with "
        "it): darker or farther surfaces than the sheet allows return nothing.", 5, 1, log=True),
    "returns_blind_zone": ParamDoc(
        "blind zone", "m", "Nearest range the sensor reports: echoes nearer than this are dropped.", 0.05, 2),
    "returns_false_alarm_rate": ParamDoc(
        "false alarms", "/pulse", "Probability that a pulse which hits nothing reports a noise point anyway "
        "(tagged as noise).", 1e-5, 6),
    "returns_divergence_h": ParamDoc(
        "divergence H", "deg", "Horizontal beam divergence (full angle): the footprint's width, which blends "
        "edges into mixed points and second returns.", 0.005, 3, log=True),
    "returns_divergence_v": ParamDoc(
        "divergence V", "deg", "Vertical beam divergence (full angle): the footprint's height.", 0.005, 3,
        log=True),
    "returns_angular_sigma": ParamDoc(
        "angle noise", "deg", "1-sigma noise of each point's direction.", 0.005, 4),
}


def param_doc(name: str) -> ParamDoc:
    """The :class:`ParamDoc` of a key of :data:`~livox_viz.config.sensor.PARAM_RANGES`.

    Raises
    ------
    KeyError
        For a name that is not a tunable parameter.
    """
    return _DOCS[name]


def value_bounds(name: str) -> tuple[float, float]:
    """The closed interval a control may take: the allowed range with open ends moved inside by one fine step.

    Parameters
    ----------
    name : str
        A key of :data:`~livox_viz.config.sensor.PARAM_RANGES`.

    Returns
    -------
    low, high : float
        In the parameter's unit.
    """
    spec: ParamRange = PARAM_RANGES[name]
    doc = _DOCS[name]
    nudge = 1.0 if spec.integer else doc.fine_step
    low = spec.low + nudge if spec.low_open else spec.low
    high = spec.high - nudge if spec.high_open else spec.high
    return float(low), float(high)


def slider_fraction(name: str, value: float) -> float:
    """Where ``value`` stands on the parameter's slider, 0 to 1 (log scale where :attr:`ParamDoc.log`).

    Parameters
    ----------
    name : str
    value : float
        In the parameter's unit.
    """
    low, high = value_bounds(name)
    value = min(max(value, low), high)
    if _DOCS[name].log and low > 0:
        return math.log(value / low) / math.log(high / low)
    return (value - low) / (high - low) if high > low else 0.0


def slider_value(name: str, fraction: float) -> float:
    """The value at ``fraction`` (0 to 1) of the parameter's slider: the inverse of :func:`slider_fraction`,
    rounded to the decimals shown (and to a whole number for an integer parameter)."""
    low, high = value_bounds(name)
    fraction = min(max(fraction, 0.0), 1.0)
    doc = _DOCS[name]
    if doc.log and low > 0:
        value = low * (high / low) ** fraction
    else:
        value = low + fraction * (high - low)
    value = round(value, doc.decimals)
    if PARAM_RANGES[name].integer:
        value = float(round(value))
    return min(max(value, low), high)


def describe(name: str) -> str:
    """The tooltip of a parameter: what it does, its RflySim field and its allowed range with the unit."""
    spec = PARAM_RANGES[name]
    doc = _DOCS[name]
    unit = f" {doc.unit}" if doc.unit else ""
    return f"{doc.help}\n{spec.name} ({spec.label}); allowed: {spec.describe()}{unit}"
