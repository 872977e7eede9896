"""Which laser fired each row of a scan table, found from the rows' geometry.

A head fires its K lasers in turn, each through the same moving optics from
its own small offset, so at any moment the K lasers sit at K distinct points
that all move alike. The public tables list them in one fixed order (row r is
laser r mod K), but an export need not: the order may drift from one stretch
of rows to the next, rows may be missing, the table may be cut anywhere.

:func:`assign_lasers` therefore follows the lasers as K tracks through the
rows in time order (:func:`_follow`, compiled): each track is predicted to a
row's time from its last row and the common motion (the mean of the two
velocities, at its last row and now: exact to second order, so a laser missing
for several firings is still found), and the row goes to the nearest
prediction. The tracks start from the first rows' offsets from their local
motion (a quadratic in time, fitted over a few firing groups), clustered into
K by k-means. K is the smallest count whose prediction error is within
:data:`COUNT_MARGIN` x the best of 1 to :data:`MAX_LASERS` on the first rows: one
laser too few leaves errors as large as the lasers' spacing, one too many
changes nothing. When the tracks agree with one fixed order (row at slot s is
laser (s + c) mod K for at least :data:`IN_ORDER_SHARE` of the rows) the fixed
order is used exactly, as the public tables have it. A forced count the
geometry does not see is taken in one fixed order (row at slot s is laser
s mod K).

Which laser a row is need not say when it fired. A head may fire its K lasers
together, or in turn at fixed offsets, and an export list each group of K in
any order (sorted within a group by angle, or at random), each row's time
then that of its place in the list, not of its firing. When the rows come in
groups of K consecutive slots that each hold every laser once, the lasers are
followed a second time with every row of a group at the group's first slot
(:func:`_group_slots`); if that predicts the rows at least
:data:`GROUP_GAIN` x closer, the rows' own slots were their places in a list,
and each row is taken at its group's slot (``LaserAssignment.slots``). A
laser fired at a fixed offset within its group is then at a fixed time shift
from its group's slot, which its own coefficients take up exactly.

Lasers are numbered by slot (laser k fires at slots k mod K) when in order,
else by their offsets: from the top down (y), then from the left (x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from livox_viz.core.compiled import LazyKernels

MAX_LASERS = 16
#: The smallest laser count whose prediction error is within this factor of the best count's is taken.
COUNT_MARGIN = 3.0
#: Rows the laser count is chosen on (from the table's start).
COUNT_ROWS = 24_000
#: Share of rows that must agree with one fixed order for it to be used.
IN_ORDER_SHARE = 0.99
#: Share of groups of K rows that must each hold every laser once for the rows to be tried at their group's slot.
GROUP_SHARE = 0.9
#: The rows are taken at their group's slot when that predicts them at least this many times closer.
GROUP_GAIN = 0.5


@dataclass(frozen=True)
class LaserAssignment:
    """Each row's laser.

    Parameters
    ----------
    lasers : int
        K, the lasers in use (``found`` unless forced).
    found : int
        K as the rows' geometry says it.
    labels : (n,) int8
        Each row's laser, 0 .. K - 1.
    in_order : bool
        Whether ``labels`` is ``slot mod K`` (the lasers fire in one fixed order).
    prediction_error_deg : float
        Rms distance of each row from where its laser's track was predicted (degrees of the plane): small
        for a scan, as large as the rows' spread for noise.
    slots : (n,) int64
        Each row's firing slot as the fit takes it: the table's own, or, when ``grouped``, its group's first.
    grouped : bool
        Whether the rows were listed in groups of K in no fixed order, each taken at its group's slot.
    """

    lasers: int
    found: int
    labels: np.ndarray
    in_order: bool
    prediction_error_deg: float
    slots: np.ndarray
    grouped: bool = False


def find_lasers(z: np.ndarray, max_lasers: int = MAX_LASERS) -> int:
    """K, the number of lasers firing in one fixed order, from the period of the row-to-row steps.

    For each candidate K the mean change between a step and the step K rows
    later is small only at the true K (and its multiples): the smallest K whose
    score is within 1.5 x the best wins.

    Parameters
    ----------
    z : (n,) complex128
        The table's points, degrees (x + iy), every firing in order.
    """
    steps = np.diff(z)
    scores = []
    for k in range(1, min(max_lasers, steps.size // 8) + 1):
        scores.append(float(np.mean(np.abs(steps[k:] - steps[:-k]))))
    if not scores:
        return 1
    best = min(scores)
    return next(k for k, score in enumerate(scores, start=1) if score <= 1.5 * best)


def assign_lasers(z: np.ndarray, slots: np.ndarray, beams: int | None = None) -> LaserAssignment:
    """Each row's laser, from the geometry (see the module notes).

    Parameters
    ----------
    z : (n,) complex128
        The rows' points, degrees (x + iy; a panorama's azimuth unwrapped), in time order.
    slots : (n,) int64
        Each row's firing slot (increasing).
    beams : int, optional
        Force K.
    """
    z = np.asarray(z, dtype=np.complex128)
    slots = np.asarray(slots, dtype=np.int64)
    head = min(z.size, COUNT_ROWS)
    errors = {k: _follow_rows(z[:head], slots[:head], k)[1] for k in range(1, min(MAX_LASERS, head // 16) + 1)}
    best = min(errors.values()) if errors else 0.0
    found = next((k for k, error in errors.items() if error <= COUNT_MARGIN * best), 1)
    lasers = beams or found
    if lasers == 1:
        return LaserAssignment(1, found, np.zeros(z.size, dtype=np.int8), True, errors.get(1, 0.0), slots)
    # Rows that share a slot (a group printed with one time) in their listed order, for the fixed order's test.
    run_start = np.flatnonzero(np.r_[True, np.diff(slots) != 0])
    rank = np.arange(slots.size) - np.repeat(run_start, np.diff(np.r_[run_start, slots.size]))
    residue = np.mod(slots + rank, lasers).astype(np.int8)
    if lasers != found:
        # A count the geometry does not see (K tracks on fewer lasers follow nothing in particular): the lasers
        # are taken to fire in turn in one fixed order, as a forced count says.
        return LaserAssignment(lasers, found, residue, True, errors.get(found, 0.0), slots)
    labels, error = _follow_rows(z, slots, lasers)
    # The tracks in one fixed order: each track's most common slot residue, all distinct and agreeing.
    counts = np.zeros((lasers, lasers), dtype=np.int64)
    np.add.at(counts, (labels, residue), 1)
    mapping = counts.argmax(axis=1)
    agree = counts[np.arange(lasers), mapping].sum() / max(1, z.size)
    if np.unique(mapping).size == lasers and agree >= IN_ORDER_SHARE:
        return LaserAssignment(lasers, found, residue, True, error, slots)
    grouped = _group_slots(slots, labels, lasers)
    if grouped is not None:
        group_labels, group_error = _follow_rows(z, grouped, lasers)
        if group_error <= GROUP_GAIN * error:
            return LaserAssignment(lasers, found, _by_offset(z, grouped, group_labels, lasers), False, group_error,
                                   grouped, True)
    return LaserAssignment(lasers, found, _by_offset(z, slots, labels, lasers), False, error, slots)


def _group_slots(slots: np.ndarray, labels: np.ndarray, lasers: int) -> np.ndarray | None:
    """Each row at the first slot of its group of ``lasers`` rows, or None when the rows are not such groups.

    The groups are ``lasers`` consecutive rows from one of the ``lasers`` phases (a table may be cut within a
    group), each on ``lasers`` consecutive slots (no firing missing); the phase whose groups most often hold
    every laser once is taken, if at least :data:`GROUP_SHARE` of its whole groups do. Rows of a cut group at
    either end keep the slots their whole group would have.
    """
    n = slots.size
    best, best_share = -1, 0.0
    for phase in range(lasers):
        whole = (n - phase) // lasers
        if whole < 2:
            continue
        block = slice(phase, phase + whole * lasers)
        grouped_slots = slots[block].reshape(whole, lasers)
        if not np.all(grouped_slots[:, -1] - grouped_slots[:, 0] == lasers - 1):
            continue
        grouped_labels = np.sort(labels[block].reshape(whole, lasers), axis=1)
        share = float(np.mean(np.all(grouped_labels == np.arange(lasers), axis=1)))
        if share > best_share:
            best, best_share = phase, share
    if best < 0 or best_share < GROUP_SHARE:
        return None
    group = np.floor_divide(np.arange(n) - best, lasers)
    return (slots[best] + lasers * group).astype(np.int64)


def even_series(z: np.ndarray, slots: np.ndarray, lasers: int) -> np.ndarray:
    """One laser's rows as an evenly spaced series, one value every ``lasers`` firings, for its spectrum.

    Each row goes to the firing group its slot falls in; a group without a row of this laser holds zero, the
    rows' mean taken out first so that the gaps add no line.

    Parameters
    ----------
    z : (n,) complex128
        The laser's rows, in time order.
    slots : (n,) int64
        Their firing slots.
    lasers : int
        K: the series' spacing is K firings.
    """
    if z.size and np.all(np.diff(slots) == lasers):
        return np.asarray(z, dtype=np.complex128)
    cell = (slots - slots[0] + lasers // 2) // lasers
    even = np.zeros(int(cell[-1]) + 1, dtype=np.complex128)
    even[cell] = z - z.mean()
    return even


def _by_offset(z: np.ndarray, slots: np.ndarray, labels: np.ndarray, lasers: int) -> np.ndarray:
    """Labels renumbered by each laser's offset from the rows' local mean: top first, then left first."""
    local = _local_offsets(z, slots, lasers)
    means = np.array([local[labels == k].mean() if np.any(labels == k) else 0.0 for k in range(lasers)])
    order = np.lexsort((np.round(means.real, 6), -np.round(means.imag, 6)))
    rename = np.empty(lasers, dtype=np.int8)
    rename[order] = np.arange(lasers)
    return rename[labels]


def _local_offsets(z: np.ndarray, slots: np.ndarray, lasers: int, rows: int = 50_000) -> np.ndarray:
    """Each row's offset from a quadratic in time fitted to the rows within about two firing groups of it."""
    n = z.size
    half = max(2, 2 * lasers)
    out = np.empty(n, dtype=np.complex128)
    for start in range(0, n, rows):
        stop = min(n, start + rows)
        i = np.arange(start, stop)
        j = np.clip(i[:, None] + np.arange(-half, half + 1)[None, :], 0, n - 1)
        u = (slots[j] - slots[i][:, None]).astype(np.float64) / half
        design = np.stack([np.ones_like(u), u, u * u], axis=-1)
        normal = np.einsum("mwp,mwq->mpq", design, design) + 1e-9 * np.eye(3)
        rhs = np.einsum("mwp,mw->mp", design, z[j])
        out[start:stop] = z[start:stop] - np.linalg.solve(normal, rhs[..., None])[:, 0, 0]
    return out


def _follow_rows(z: np.ndarray, slots: np.ndarray, lasers: int) -> tuple[np.ndarray, float]:
    """Labels and the rms prediction error of following ``lasers`` tracks through the rows."""
    if z.size == 0:
        return np.zeros(0, dtype=np.int64), 0.0
    start = min(z.size, 16 * lasers)
    offsets = _local_offsets(z[: start + 4 * lasers], slots[: start + 4 * lasers], lasers)[:start]
    seeds = _kmeans(offsets, lasers)
    # The common motion at the start: a line through the first rows less their clusters' offsets.
    centred = z[:start] - np.array([offsets[seeds == k].mean() if np.any(seeds == k) else 0.0
                                    for k in range(lasers)])[seeds]
    u = slots[:start].astype(np.float64)
    velocity = np.polyfit(u - u[0], centred, 1)[0] if start > 2 and np.ptp(u) > 0 else 0j
    # Each track starts at its cluster's row nearest the middle of the first rows (the local fit is poorest at
    # the table's very start); the rows before it are predicted back from there.
    track = np.zeros((lasers, 3))  # x, y, slot of each track's last row
    for k in range(lasers):
        members = np.flatnonzero(seeds == k)
        row = int(members[np.argmin(np.abs(members - start // 2))]) if members.size else 0
        track[k] = z[row].real, z[row].imag, slots[row]
    labels = np.empty(z.size, dtype=np.int64)
    errors = np.empty(z.size)
    _KERNELS("follow")(np.ascontiguousarray(z.real), np.ascontiguousarray(z.imag), slots.astype(np.float64), track,
                       float(velocity.real), float(velocity.imag), labels, errors)
    scored = errors[start:] if z.size > 2 * start else errors
    return labels, math.sqrt(float(np.mean(scored**2)))


def _kmeans(points: np.ndarray, clusters: int, rounds: int = 20) -> np.ndarray:
    """Labels of complex points in ``clusters`` groups (farthest-point start, then Lloyd's rounds)."""
    centres = [points[int(np.argmax(np.abs(points - points.mean())))]]
    for _ in range(clusters - 1):
        distance = np.min(np.abs(points[:, None] - np.array(centres)[None, :]), axis=1)
        centres.append(points[int(np.argmax(distance))])
    centre = np.array(centres)
    labels = np.zeros(points.size, dtype=np.int64)
    for _ in range(rounds):
        labels = np.argmin(np.abs(points[:, None] - centre[None, :]), axis=1)
        for k in range(clusters):
            if np.any(labels == k):
                centre[k] = points[labels == k].mean()
    return labels


def _follow(x: np.ndarray, y: np.ndarray, slots: np.ndarray, track: np.ndarray, vx: float, vy: float,
            labels: np.ndarray, errors: np.ndarray) -> None:
    """Give each row to the nearest predicted track (``labels``, the distance in ``errors``) and move that track
    there. ``track`` (K, 3) holds x, y and slot of each track's last row; the common velocity (per slot) follows
    every row's own laser, and a track is predicted with the mean of its velocity then and now."""
    lasers = track.shape[0]
    then_x = np.full(lasers, vx)
    then_y = np.full(lasers, vy)
    for i in range(x.size):
        best = 0
        best_distance = 1e300
        for k in range(lasers):
            gap = slots[i] - track[k, 2]
            px = track[k, 0] + 0.5 * (then_x[k] + vx) * gap
            py = track[k, 1] + 0.5 * (then_y[k] + vy) * gap
            distance = (x[i] - px) ** 2 + (y[i] - py) ** 2
            if distance < best_distance:
                best_distance = distance
                best = k
        labels[i] = best
        errors[i] = math.sqrt(best_distance)
        gap = slots[i] - track[best, 2]
        if gap > 0:
            weight = min(1.0, gap / (4.0 * lasers))
            vx += weight * ((x[i] - track[best, 0]) / gap - vx)
            vy += weight * ((y[i] - track[best, 1]) / gap - vy)
        track[best, 0] = x[i]
        track[best, 1] = y[i]
        track[best, 2] = slots[i]
        then_x[best] = vx
        then_y[best] = vy


_KERNELS = LazyKernels(globals())
