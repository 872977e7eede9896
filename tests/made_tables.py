"""Scan tables made from the shipped ones as other exports and recordings give them (issue 33 §3).

- **Out of laser order**: at each firing slot the head fires one of its K lasers,
  but which one drifts: group g fires its lasers in the order of a rotation by a
  phase that steps at random every few dozen groups, and some stretches run the
  order backwards. Each row is the position of the laser that fires at that
  slot, *at that slot's time*: every laser's own samples (every K-th row of the
  shipped table) are interpolated by a quintic spline, which follows the public
  tables to about 4e-6 deg (their own float32 step), so a made table is still
  one exact track sampled at known times.
- **Cut**: at an odd length (a spreadsheet's 1,048,575 rows is one).
- **Thinned**: rows dropped at random, as a recording misses the pulses that
  returned nothing; the kept rows carry their times.

Nothing here uses livox_viz: the tables are made from the README's definition
of the ``.npy`` form (``[theta, phi]`` radians, row r of the shipped table at
r / rate).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

TABLES = Path(__file__).resolve().parent.parent / "presets" / "tables"


@dataclass(frozen=True)
class MadeTable:
    """A made table: ``angles`` (n, 2) [theta, phi] radians, each row's firing ``slot`` (the shipped table's row
    that fired at the same time) and ``laser`` (the shipped table's numbering), at ``rate`` firings per second."""

    angles: np.ndarray
    slot: np.ndarray
    laser: np.ndarray
    rate: float

    @property
    def t(self) -> np.ndarray:
        """Each row's firing time, seconds."""
        return self.slot / self.rate

    def save_npy(self, path: Path) -> Path:
        np.save(path, self.angles.astype(np.float32))
        return path

    def save_npz(self, path: Path) -> Path:
        np.savez(path, theta=self.angles[:, 0], phi=self.angles[:, 1], t=self.t)
        return path

    def save_csv(self, path: Path, time_decimals: int = 9) -> Path:
        """As a Livox CSV (``Time/s,Azimuth/deg,Zenith/deg``), the times printed to ``time_decimals``."""
        azimuth = np.degrees(self.angles[:, 0])
        zenith = 90.0 - np.degrees(self.angles[:, 1])
        lines = ["Time/s,Azimuth/deg,Zenith/deg"]
        lines += [f"{t:.{time_decimals}f},{a:.7f},{z:.7f}" for t, a, z in zip(self.t, azimuth, zenith, strict=True)]
        path.write_text("\n".join(lines) + "\n")
        return path


def shipped(name: str, rows: int | None = None) -> np.ndarray:
    """The first ``rows`` of a shipped table, ``(n, 2)`` float64 [theta, phi] radians."""
    return np.array(np.load(TABLES / f"{name}.npy", mmap_mode="r")[:rows], dtype=np.float64)


def drifting_orders(groups: int, lasers: int, rng: np.random.Generator) -> np.ndarray:
    """``(groups, lasers)`` which laser fires at each slot of each group: a rotation whose phase steps by one
    every 20-200 groups, read backwards in every third stretch."""
    orders = np.empty((groups, lasers), dtype=np.int64)
    phase, g, stretch = 0, 0, 0
    base = np.arange(lasers)
    while g < groups:
        length = int(rng.integers(20, 200))
        order = np.roll(base, phase)
        if stretch % 3 == 2:
            order = order[::-1]
        orders[g : g + length] = order
        g += length
        phase = (phase + int(rng.choice([-1, 1]))) % lasers
        stretch += 1
    return orders


def out_of_order(name: str, lasers: int, rate: float, rows: int, seed: int = 0, drop: float = 0.0,
                 start: int = 0) -> MadeTable:
    """The shipped table ``name`` fired out of laser order, ``rows`` slots from slot ``start`` (any length), with a
    fraction ``drop`` of the rows dropped at random."""
    from scipy.interpolate import make_interp_spline

    rng = np.random.default_rng(seed)
    source = shipped(name)
    theta = np.unwrap(source[:, 0])
    phi = source[:, 1]
    slots = start + np.arange(rows)
    groups = -(-(slots[-1] + 1) // lasers)
    orders = drifting_orders(groups, lasers, rng)
    fired = orders[slots // lasers, slots % lasers]
    angles = np.empty((rows, 2))
    for k in range(lasers):
        own = np.arange(k, source.shape[0], lasers)
        mine = fired == k
        if own[-1] < slots[mine].max() or own[0] > slots[mine].min():
            raise ValueError("the made table must lie inside the shipped one")
        angles[mine, 0] = make_interp_spline(own, theta[own], k=5)(slots[mine])
        angles[mine, 1] = make_interp_spline(own, phi[own], k=5)(slots[mine])
    angles[:, 0] = np.mod(angles[:, 0] + np.pi, 2 * np.pi) - np.pi if np.ptp(source[:, 0]) < 4 else np.mod(
        angles[:, 0], 2 * np.pi)
    keep = rng.random(rows) >= drop
    return MadeTable(angles[keep], slots[keep], fired[keep], rate)


# A HAP-like export: lasers listed in groups in no fixed order ------------------------------------------------------
@dataclass(frozen=True)
class GroupedExport:
    """A made export of a head whose K lasers are listed in groups of K in no fixed order.

    ``angles`` (n, 2) [theta, phi] radians; ``printed`` (n,) the Time/s each row is printed with; ``fired`` (n,)
    when each row's laser truly fired, seconds; ``laser`` (n,) the source track's laser; ``rate`` rows per second.
    """

    angles: np.ndarray
    printed: np.ndarray
    fired: np.ndarray
    laser: np.ndarray
    rate: float

    def save_csv(self, path: Path, time_decimals: int = 9) -> Path:
        """As a Livox CSV (``Time/s,Azimuth/deg,Zenith/deg``), the printed times to ``time_decimals``."""
        table = np.column_stack([self.printed, np.degrees(self.angles[:, 0]), 90.0 - np.degrees(self.angles[:, 1])])
        with path.open("w") as handle:
            handle.write("Time/s,Azimuth/deg,Zenith/deg\n")
            np.savetxt(handle, table, fmt=[f"%.{time_decimals}f", "%.7f", "%.7f"], delimiter=",")
        return path

    def save_npy(self, path: Path) -> Path:
        np.save(path, self.angles.astype(np.float32))
        return path


def grouped_export(track, rate: float, rows: int, listing: str, together: bool, seed: int = 0) -> GroupedExport:
    """``rows`` rows of a track's K lasers (a :class:`~livox_viz.config.track_params.TrackParams`; made with
    livox_viz's own ``track_xy``, as no public table of such a head is at hand), listed in groups of K.

    ``together``: the K lasers of a group fire at one instant and the group is printed with that time (each row
    of it the same Time/s); else laser k fires at slot g K + k and each row is printed with the time of its place
    in the list (so a row's Time/s is not when it fired). ``listing`` orders each group: ``"random"`` (a new
    order each group), ``"azimuth"`` (left to right), ``"elevation"`` (top down) or ``"fixed"`` (laser order).
    """
    from livox_viz.patterns.planes import directions_from_xy
    from livox_viz.patterns.track import track_xy

    lasers = track.lasers
    slot = np.arange(rows)
    laser = slot % lasers
    fired = ((slot - laser) if together else slot) / rate
    xy = track_xy(track, fired, laser)
    whole = rows // lasers * lasers
    groups = xy[:whole].reshape(-1, lasers, 2)
    rng = np.random.default_rng(seed)
    keys = {"random": rng.random(groups.shape[:2]), "azimuth": groups[..., 0], "elevation": -groups[..., 1],
            "fixed": np.broadcast_to(np.arange(lasers, dtype=np.float64), groups.shape[:2])}[listing]
    order = np.arange(rows)
    order[:whole] = (np.argsort(keys, axis=1, kind="stable") + np.arange(0, whole, lasers)[:, None]).ravel()
    d = directions_from_xy(xy[order])  # FRD: x forward, y right, z down
    angles = np.column_stack([np.arctan2(-d[:, 1], d[:, 0]), np.arcsin(np.clip(-d[:, 2], -1.0, 1.0))])
    printed = fired[order] if together else slot / rate
    return GroupedExport(angles, printed, fired[order], laser[order], rate)
