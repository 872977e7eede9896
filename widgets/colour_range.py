"""A colour range the user fixes for the scene's colouring (View > Colour range...), without Qt: the colourings
that take one, a typed pair checked, and its words.

ParaView's "Rescale to custom range": the scene's colour bar spans the two numbers typed, for the colouring in
use, until "Automatic" gives it the data's range back. Each colouring keeps its own (a range in metres means
nothing to the time colouring). The return/tag colouring is classes, not a scale: it takes none.
"""

from __future__ import annotations

import math

from livox_viz import LivoxVizError

#: The scene colourings whose range may be fixed, and the unit of their numbers.
RANGE_UNITS: dict[str, str] = {"range": "m", "height": "m", "time": "s", "reflectivity": ""}
_ALLOWED = "allowed: two numbers, min below max (or Automatic)"


def _number(text: str, which: str, mode: str) -> float:
    try:
        value = float(str(text).strip())
    except ValueError:
        raise LivoxVizError(f"colour range of the {mode} colouring: {which} {str(text).strip()!r} is not a number; "
                            f"{_ALLOWED}") from None
    if not math.isfinite(value):
        raise LivoxVizError(f"colour range of the {mode} colouring: {which} {value} is not a finite number; "
                            f"{_ALLOWED}")
    return value


def parse_colour_range(mode: str, low: str, high: str) -> tuple[float, float]:
    """The colour range typed for the scene colouring ``mode``, checked.

    Parameters
    ----------
    mode : str
        A scene colouring (:data:`~livox_viz.widgets.session.SCENE_COLOURS`).
    low, high : str
        The min and max as typed, in the colouring's unit (:data:`RANGE_UNITS`).

    Returns
    -------
    (float, float)
        ``(low, high)``, finite, ``low < high``.

    Raises
    ------
    LivoxVizError
        In one line: what is wrong and what is allowed.
    """
    if mode not in RANGE_UNITS:
        raise LivoxVizError(f"the {mode} colouring is classes, not a scale: it has no colour range; allowed: "
                            f"{', '.join(RANGE_UNITS)}")
    lo, hi = _number(low, "min", mode), _number(high, "max", mode)
    if not lo < hi:
        raise LivoxVizError(f"colour range of the {mode} colouring: min {lo:g} is not below max {hi:g}; {_ALLOWED}")
    if mode == "reflectivity" and lo <= 0:
        # Its bar is logarithmic (1 to 255): zero and below have no place on it.
        raise LivoxVizError(f"colour range of the reflectivity colouring: min {lo:g}; allowed: above 0 (its scale "
                            "is logarithmic), below max")
    return lo, hi


def range_words(mode: str, bounds: tuple[float, float]) -> str:
    """A fixed range as the heads-up text says it, e.g. ``"fixed 5 to 40 m"``."""
    unit = RANGE_UNITS.get(mode, "")
    return f"fixed {bounds[0]:g} to {bounds[1]:g}{' ' + unit if unit else ''}"
