"""The rosette scan pattern: arcs, petals, figure-8s, flowers and figures, streamed.

Coordinates are angles in degrees in the sensor's angular plane (pattern x to
the sensor's right, pattern y up; see :mod:`livox_viz.casting.directions`). The maths
is section 2-4 of ``scan-model.md``; the decisions it leaves to us are:

* **Arc ends**: an outward arc samples i = 0 .. W-1 (centre to tip), an inward
  arc i = W .. 1, so a petal holds its centre and its tip once each.
* **Figure-8 order**: upper-left outward, lower-left inward, upper-right
  outward, lower-right inward: one smooth path through the centre.
* **Centre-side half of an arc**: x linear in X (x = X*c) on the circle through
  the centre and the tip with sagitta h. When h exceeds FOV/4 that circle is
  more than a half circle and y is no function of x; the half is then sampled
  linearly in the circle's own angle, which keeps the arc continuous and
  smooth at its top (-FOV/4, h).
* **FOV**: the field of view is a cone of half-angle FOV/2; the rare samples of
  extreme parameters (q < 1 near the tip, large h) that fall outside it are
  moved radially onto its edge, as the real sensor cannot see beyond it.
* **Jitter**: a random rotation U(0,1) * otherParams[6] degrees is added to a
  running offset after each flower (``jitter_scope="flower"``, default) or
  after each figure (``"figure"``).

Randomness comes from ``numpy.random.default_rng(seed)``: the same
configuration and seed give bit-identical points however the stream is cut."""

from __future__ import annotations

import math

import numpy as np

from livox_viz.config.sensor import SensorConfig
from livox_viz.patterns.stream import PatternChunk, PatternStream

#: The four arcs of a figure-8, by their number 0..3 in scan order.
ARC_NAMES: tuple[str, ...] = (
    "upper-left outward",
    "lower-left inward",
    "upper-right outward",
    "lower-right inward",
)


_FIGURE8S_PER_BLOCK = 4096


def arc_xy(
    sample_index: np.ndarray,
    data_width: int,
    camera_fov: float,
    petal_height: float,
    spacing_exponent: float,
    tip_exponent: float,
) -> np.ndarray:
    """Points of the upper arc (half a petal) between the centre and the tip.

    Parameters
    ----------
    sample_index : (n,) float64
        Sample numbers i in [0, W]: 0 is the pattern centre, W the tip.
    data_width : int
        W, points per arc.
    camera_fov : float
        Full field of view, degrees; the tip lies at (-FOV/2, 0).
    petal_height : float
        h, the petal's height: how far the arc rises from the petal's axis at its middle (half the petal's
        width), degrees.
    spacing_exponent : float
        p: X = -(i/W)**p.
    tip_exponent : float
        q, the calibration exponent of the tip-side part.

    Returns
    -------
    xy : (n, 2) float64
        Pattern x, y in degrees, y >= 0, inside the FOV circle.
    """
    index = np.asarray(sample_index, dtype=np.float64)
    big_x = -((index / data_width) ** spacing_exponent)
    half_length = camera_fov / 4.0  # R
    petal_length = camera_fov / 2.0  # c
    h = petal_height
    x = np.empty_like(big_x)
    y = np.empty_like(big_x)

    tip = big_x < -0.5
    angle = big_x[tip] * math.pi
    x[tip] = -half_length * np.abs(np.cos(angle)) ** tip_exponent - half_length
    y[tip] = h * np.abs(np.sin(angle)) ** tip_exponent

    centre = ~tip
    circle_radius = (half_length**2 + h**2) / (2.0 * h)
    circle_centre_y = h - circle_radius
    if h <= half_length:
        xc = big_x[centre] * petal_length
        x[centre] = xc
        # (h - Rc) + sqrt(Rc^2 - (x+R)^2), rewritten so y is exactly 0 at x = 0 and x = -c.
        root = np.sqrt(np.maximum(circle_radius**2 - (xc + half_length) ** 2, 0.0))
        y[centre] = -xc * (xc + petal_length) / (root + (circle_radius - h))
    else:
        start = math.atan2(-circle_centre_y, half_length)
        fraction = -2.0 * big_x[centre]
        phi = start + fraction * (math.pi / 2.0 - start)
        x[centre] = -half_length + circle_radius * np.cos(phi)
        y[centre] = circle_centre_y + circle_radius * np.sin(phi)

    xy = np.stack([x, y], axis=-1)
    radius = np.hypot(x, y)
    outside = radius > petal_length
    if np.any(outside):
        xy[outside] *= (petal_length / radius[outside])[:, None]
    return xy


def config_arc_xy(config: SensorConfig, sample_index: np.ndarray) -> np.ndarray:
    """:func:`arc_xy` with the parameters of ``config``; ``sample_index`` (n,) -> (n, 2)."""
    return arc_xy(
        sample_index,
        config.data_width,
        config.camera_fov,
        config.petal_height,
        config.spacing_exponent,
        config.tip_exponent,
    )


def figure8_template(config: SensorConfig) -> np.ndarray:
    """The unrotated figure-8 as a complex path, x + iy in degrees.

    Returns
    -------
    path : (4W,) complex128
        Arcs in scan order: upper-left outward (i = 0..W-1), lower-left
        inward (i = W..1), upper-right outward, lower-right inward.
    """
    width = config.data_width
    outward = config_arc_xy(config, np.arange(0, width, dtype=np.float64))
    inward = config_arc_xy(config, np.arange(width, 0, -1, dtype=np.float64))
    out_c = outward[:, 0] + 1j * outward[:, 1]
    in_c = inward[:, 0] + 1j * inward[:, 1]
    return np.concatenate([out_c, np.conj(in_c), -np.conj(out_c), -in_c])


def petal_xy(config: SensorConfig) -> np.ndarray:
    """One closed petal (the left one of a figure-8): ``(2W, 2)`` float64 degrees."""
    template = figure8_template(config)[: 2 * config.data_width]
    return np.stack([template.real, template.imag], axis=-1)


class ScanPattern(PatternStream):
    """The endless, seedable point stream of one sensor configuration.

    Parameters
    ----------
    config : SensorConfig
        The sensor.
    seed : int
        Seed of the one random generator (figure-8 order and jitter).

    Examples
    --------
    >>> from livox_viz import load_preset, ScanPattern
    >>> pattern = ScanPattern(load_preset("livox_mid70"), seed=0)
    >>> frame = pattern.next_frame()
    >>> frame.xy_deg.shape
    (10000, 2)
    """

    def __init__(self, config: SensorConfig, seed: int = 0) -> None:
        self.config = config
        self.seed = int(seed)
        self._rng = np.random.default_rng(self.seed)
        self._template = figure8_template(config)
        self._position = 0
        n8 = config.figure8_per_flower
        self._flowers_per_block = max(1, _FIGURE8S_PER_BLOCK // n8)
        self._blocks: dict[int, np.ndarray] = {}
        self._next_block = 0
        self._offset_deg = 0.0

    def points(self, start: int, count: int) -> PatternChunk:
        """Points ``start .. start+count-1`` of the stream, without moving it.

        ``start`` must not lie before figure-8s already dropped from memory:
        the stream keeps only the random draws of the blocks it is working on.
        """
        per8 = self.config.points_per_figure8
        stop = start + count
        first8 = start // per8
        last8 = (stop - 1) // per8 + 1 if count else first8
        angles = self._figure8_angles(first8, last8)
        rotation = np.exp(1j * np.deg2rad(angles))
        path = self._path_buffer(count)
        _rotate_into(path, self._template, rotation, start - first8 * per8)
        return PatternChunk(self.config, start, path.view(np.float64).reshape(count, 2),
                            figure8_angle_deg=angles)

    # Random draws, one block of flowers at a time ---------------------------------
    def _figure8_angles(self, first: int, last: int) -> np.ndarray:
        """Rotation of figure-8s ``first .. last-1`` in degrees, ``(last-first,)``."""
        n8 = self.config.figure8_per_flower
        per_block = self._flowers_per_block * n8
        first_block = first // per_block
        last_block = max(first_block, (last - 1) // per_block)
        if first_block < min(self._blocks, default=self._next_block):
            raise ValueError("points() cannot go back before the blocks the stream has dropped")
        while self._next_block <= last_block:
            self._blocks[self._next_block] = self._draw_block()
            self._next_block += 1
        for old in [b for b in self._blocks if b < first_block]:
            del self._blocks[old]
        angles = np.concatenate([self._blocks[b] for b in range(first_block, last_block + 1)])
        offset = first_block * per_block
        return angles[first - offset : last - offset]

    def _draw_block(self) -> np.ndarray:
        cfg = self.config
        n8 = cfg.figure8_per_flower
        flowers = self._flowers_per_block
        first_flower = self._next_block * flowers
        order = np.argsort(self._rng.random((flowers, n8)), axis=1)
        jitter = self._rng.random(flowers) * cfg.jitter_max_deg
        flower_number = first_flower + np.arange(flowers)
        within_figure = flower_number % cfg.flowers_per_figure
        if cfg.jitter_scope == "figure":
            jitter = np.where(within_figure == cfg.flowers_per_figure - 1, jitter, 0.0)
        steps_before = np.concatenate([[0.0], np.cumsum(jitter)[:-1]])
        offsets = np.mod(self._offset_deg + steps_before, 360.0)
        self._offset_deg = float(np.mod(self._offset_deg + jitter.sum(), 360.0))
        flower_angle = offsets + within_figure * cfg.flower_step_deg
        angles = flower_angle[:, None] + order * cfg.petal_spacing_deg
        return np.mod(angles, 360.0).ravel()


def _rotate_into(out: np.ndarray, template: np.ndarray, rotation: np.ndarray, head: int) -> None:
    """Fill ``out`` (n,) with figure-8s: the template times each rotation, from ``head`` on.

    Parameters
    ----------
    out : (n,) complex128
        Destination.
    template : (P,) complex128
        One unrotated figure-8.
    rotation : (m,) complex128
        Unit rotation of each figure-8 ``out`` touches.
    head : int
        Where in the first figure-8 ``out`` starts, 0 <= head < P.
    """
    count = out.shape[0]
    period = template.shape[0]
    if count == 0:
        return
    if head + count <= period:
        np.multiply(template[head : head + count], rotation[0], out=out)
        return
    first = period - head
    np.multiply(template[head:], rotation[0], out=out[:first])
    full = (count - first) // period
    if full:
        body = out[first : first + full * period].reshape(full, period)
        np.multiply(template[None, :], rotation[1 : 1 + full, None], out=body)
    rest = count - first - full * period
    if rest:
        np.multiply(template[:rest], rotation[1 + full], out=out[count - rest :])
