"""A measured pattern as the fits take it: each row's angles, its firing time, the table's rate and where it came from.

Rows are in firing order but need not be every firing: a recording misses the
pulses that returned nothing, and an export may be cut anywhere. Each row's
time is a whole number of firing periods (its *slot*, ``t * rate``) from the
first row's, so a table with gaps is still a set of samples of one track at
known times. A table read without times has consecutive slots (row r at
r / rate).

The readers are in :mod:`~livox_viz.fitting.reference`; this module holds only
the data, so that the fits and the readers can both use it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from livox_viz.config.fov import FieldOfView
from livox_viz.core.errors import LivoxVizError

#: The four mirror images of a pattern: the signs of its (x, y) in the pattern plane (x to the right, y up).
#: Livox's simulation tables of some heads are images of the real sensor's pattern (found by fitting frames the
#: hardware recorded, :mod:`~livox_viz.fitting.recording_fit`); the shipped tables' index says which.
PLANE_IMAGES: dict[str, tuple[int, int]] = {
    "as printed": (1, 1),
    "mirrored left-right": (-1, 1),
    "mirrored top-bottom": (1, -1),
    "turned 180 degrees": (-1, -1),
}

#: A table whose rows all lie within this many degrees of one direction does not scan.
STILL_DEG = 1e-3


@dataclass(frozen=True)
class ReferencePattern:
    """A measured pattern.

    Parameters
    ----------
    name : str
    xy_deg : (n, 2) float64
        Pattern x (right), y (up), degrees.
    t : (n,) float64
        Firing time of each row, seconds from the first row: a whole number of firing periods
        (``slot / rate``), increasing; ``row / rate`` for a table of every firing.
    rate : float
        Firings per second (rows per second when no row is missing).
    plane : {"boresight", "panorama"}
        The pattern plane of ``xy_deg``.
    rate_source : str
        Where the rate came from, in words ("given", "the shipped tables' index", "its Time/s column",
        "read off the spectrum: ...").
    shipped : str
        The shipped table this one is or begins as (its name in ``presets/tables/index.json``), else "".
    image : str
        How the rows as printed were turned to be the real sensor's (a key of :data:`PLANE_IMAGES`; the
        shipped tables' index says it for each head, "as printed" for any other table).
    recording : str
        The format of the real sensor's recording the rows were read from ("PCD", "LVX2", ...), else "": a
        recording starts at its own phases (not a preset's) and holds only its own span (it does not repeat).
    """

    name: str
    xy_deg: np.ndarray
    t: np.ndarray
    rate: float
    plane: str = "boresight"
    rate_source: str = "given"
    shipped: str = ""
    image: str = "as printed"
    recording: str = ""

    @property
    def alpha_deg(self) -> np.ndarray:
        """``(n,)`` angle off the boresight, degrees."""
        return np.hypot(self.xy_deg[:, 0], self.xy_deg[:, 1])

    @cached_property
    def slots(self) -> np.ndarray:
        """``(n,)`` int64 each row's firing slot, ``t * rate`` (0 for the first row)."""
        return np.rint(np.asarray(self.t, dtype=np.float64) * self.rate).astype(np.int64)

    @cached_property
    def consecutive(self) -> bool:
        """Whether the rows are every firing from the first to the last (no gaps)."""
        slots = self.slots
        # Rows sharing a slot (a group printed with one time) are no firing each, even where they count right.
        return bool(slots.size == 0 or (slots[0] == 0 and slots[-1] == slots.size - 1 and np.all(np.diff(slots) > 0)))

    @property
    def firings(self) -> int:
        """Firings from the first row to the last, both counted (the rows plus the gaps); rows that share the last
        slot (a group printed with one time) each count as one."""
        if not len(self.t):
            return 0
        slots = self.slots
        return int(slots[-1] - slots[0]) + int(np.count_nonzero(slots == slots[-1]))

    @property
    def seconds(self) -> float:
        """Duration of the table: its firings over the rate."""
        return self.firings / self.rate

    @cached_property
    def field_of_view(self) -> FieldOfView:
        """What the table's rays fill: a cone when round, else their outline; a band in the panorama plane."""
        self.require_a_scan()
        return FieldOfView.of_points(self.xy_deg, self.plane)

    def require_a_scan(self) -> None:
        """Refuse a table whose rows all point one way (within :data:`STILL_DEG`): there is no track to fit."""
        extent = float(np.ptp(self.xy_deg, axis=0).max()) if len(self.xy_deg) else 0.0
        if not extent > STILL_DEG:
            raise LivoxVizError(f"{self.name}: every row points within {extent:.3g} deg of one direction; allowed: a "
                                "table whose rows trace the scan (the angles of consecutive firings)")
