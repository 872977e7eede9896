"""The scene view's range and reflectivity filter (View > Filters...), without VTK or Qt.

What CloudCompare's "Filter by value", RViz's intensity min/max and Livox
Viewer's range and reflectivity filters do: the cloud's points whose range or
reflectivity falls outside the bounds are not drawn, so they cannot be picked
either. The filter hides; it never changes what the scan holds, exports or
counts. Its masks are numpy comparisons over the ring's own arrays, so a tick
costs a few passes over the points held and no Python loop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from livox_viz.core.errors import LivoxVizError

from .ring import PointRing

#: The Livox reflectivity byte's bounds.
REFLECTIVITY_LIMITS = (0, 255)


@dataclass(frozen=True)
class CloudFilter:
    """Bounds on the points the scene view draws; None is no bound on that side.

    Parameters
    ----------
    range_min_m, range_max_m : float, optional
        The range each drawn point was measured at, metres, both bounds included (>= 0).
    reflectivity_min, reflectivity_max : int, optional
        Its reflectivity byte, both bounds included (0 to 255).

    Raises
    ------
    LivoxVizError
        A bound that is not a number of its kind, or a minimum above its maximum: one line naming the pair and
        what is allowed.
    """

    range_min_m: float | None = None
    range_max_m: float | None = None
    reflectivity_min: int | None = None
    reflectivity_max: int | None = None

    def __post_init__(self) -> None:
        for key in ("range_min_m", "range_max_m"):
            value = getattr(self, key)
            if value is not None and not (_is_number(value) and math.isfinite(value) and value >= 0):
                raise LivoxVizError(f"range filter: {value!r} m refused; allowed: a range of 0 m or more, or none")
        for key in ("reflectivity_min", "reflectivity_max"):
            value = getattr(self, key)
            low, high = REFLECTIVITY_LIMITS
            if value is not None and not (_is_number(value) and float(value).is_integer() and low <= value <= high):
                raise LivoxVizError(f"reflectivity filter: {value!r} refused; allowed: a whole number from {low} "
                                    f"to {high}, or none")
        if None not in (self.range_min_m, self.range_max_m) and self.range_min_m > self.range_max_m:
            raise LivoxVizError(f"range filter {self.range_min_m:g}-{self.range_max_m:g} m refused: its minimum is "
                                "above its maximum; allowed: minimum <= maximum")
        if None not in (self.reflectivity_min, self.reflectivity_max) \
                and self.reflectivity_min > self.reflectivity_max:
            raise LivoxVizError(f"reflectivity filter {self.reflectivity_min}-{self.reflectivity_max} refused: its "
                                "minimum is above its maximum; allowed: minimum <= maximum")

    @property
    def active(self) -> bool:
        """Whether any bound can hide a point (0 to 255 on reflectivity and 0 m on range hide none)."""
        low, high = REFLECTIVITY_LIMITS
        return ((self.range_min_m is not None and self.range_min_m > 0) or self.range_max_m is not None
                or (self.reflectivity_min is not None and self.reflectivity_min > low)
                or (self.reflectivity_max is not None and self.reflectivity_max < high))

    def keeps(self, range_m: np.ndarray, reflectivity: np.ndarray) -> np.ndarray:
        """``(n,)`` bool: which points the filter lets through.

        Parameters
        ----------
        range_m : (n,) float
            Each point's range, metres.
        reflectivity : (n,) uint8
            Each point's reflectivity byte.
        """
        keep = np.ones(len(range_m), dtype=bool)
        # In place, one bound at a time: a bound that hides nothing costs nothing.
        low, high = REFLECTIVITY_LIMITS
        if self.range_min_m is not None and self.range_min_m > 0:
            keep &= range_m >= self.range_min_m
        if self.range_max_m is not None:
            keep &= range_m <= self.range_max_m
        if self.reflectivity_min is not None and self.reflectivity_min > low:
            keep &= reflectivity >= self.reflectivity_min
        if self.reflectivity_max is not None and self.reflectivity_max < high:
            keep &= reflectivity <= self.reflectivity_max
        return keep

    def describe(self) -> str:
        """The bounds in words: ``"range 1-20 m, reflectivity >= 10"`` ("none" with no bound)."""
        parts = []
        for name, low, high, unit in (("range", self.range_min_m, self.range_max_m, " m"),
                                      ("reflectivity", self.reflectivity_min, self.reflectivity_max, "")):
            if low is not None and high is not None:
                parts.append(f"{name} {low:g}-{high:g}{unit}")
            elif low is not None:
                parts.append(f"{name} >= {low:g}{unit}")
            elif high is not None:
                parts.append(f"{name} <= {high:g}{unit}")
        return ", ".join(parts) or "none"

    def to_json(self) -> dict[str, Any]:
        """The bounds as a JSON object (a screenshot's sidecar), null for no bound."""
        return {"range_min_m": self.range_min_m, "range_max_m": self.range_max_m,
                "reflectivity_min": self.reflectivity_min, "reflectivity_max": self.reflectivity_max}

    @classmethod
    def from_json(cls, data: Any) -> CloudFilter:
        """The inverse of :meth:`to_json` (None or an empty object: no filter).

        Raises
        ------
        LivoxVizError
            An unknown key or a bad bound, in one line.
        """
        if data is None:
            return cls()
        if not isinstance(data, dict):
            raise LivoxVizError(f"filter {data!r}; allowed: an object with range_min_m, range_max_m, "
                                "reflectivity_min, reflectivity_max")
        unknown = sorted(set(data) - set(cls().to_json()))
        if unknown:
            raise LivoxVizError(f"filter: unknown {', '.join(unknown)}; allowed: range_min_m, range_max_m, "
                                "reflectivity_min, reflectivity_max")
        return cls(**data)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def filtered_slots(ring: PointRing, slots: np.ndarray, cloud_filter: CloudFilter) -> tuple[np.ndarray, int]:
    """The slots of ``slots`` whose points ``cloud_filter`` lets through, and how many of the ring's live points
    it hides (all of them counted, not only those of ``slots``: a thinned drawing hides as many of the window's).

    Parameters
    ----------
    ring : PointRing
        A ring that keeps each point's range (``sensor_frame``).
    slots : (k,) int64
        The slots a view would draw (live ones, maybe thinned).
    cloud_filter : CloudFilter

    Returns
    -------
    kept : (m,) int64
        In the order of ``slots``.
    hidden : int
    """
    if ring.range_m.shape[0] != ring.capacity:
        raise LivoxVizError("this cloud keeps no ranges to filter on; allowed: the scene view's cloud")
    keep = cloud_filter.keeps(ring.range_m, ring.reflectivity)  # every slot at once: no gather of a million slots
    kept_live = sum(int(np.count_nonzero(keep[piece])) for piece in ring.live_pieces())
    if slots.size == ring.capacity:  # every slot drawn (a full ring): the kept ones are the mask's own
        return np.flatnonzero(keep), ring.count - kept_live
    return slots[keep[slots]], ring.count - kept_live
