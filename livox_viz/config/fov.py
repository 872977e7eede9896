"""A sensor's field of view in its pattern plane: a cone, an ellipse, an outline, or a panoramic band.

Two pattern planes carry a scan's angles (degrees):

- ``"boresight"``: the polar plane of ``scan-model.md``, the angle off the
  boresight as the radius, x right, y up (every head that looks one way:
  Mid-40/70, Avia, Tele-15, Horizon, HAP).
- ``"panorama"``: azimuth and elevation for heads that see all around
  (Mid-360): x is the azimuth to the right of the sensor's x axis in
  [-180, 180) (about the FRD z axis, so positive turns right), y the elevation
  up from the sensor's x-y plane. Near the boresight both planes agree to
  first order (x right, y up).

The shapes:

- ``cone``: a circle of ``half_angle_deg`` around the boresight (the rosette's
  FOV, CameraFOV / 2; the default when a configuration has no field of view of
  its own);
- ``ellipse``: half-extents ``half_width_deg`` along x and y, e.g. the Avia's
  70.4 x 77.2 deg;
- ``outline``: a polygon (vertices in order), e.g. the Horizon's band with its
  waist, read off a table's envelope;
- ``band``: the whole horizon between two elevations (panorama plane), e.g. the
  Mid-360's -7 to 52 deg.

JSON (livox-viz's own key ``LivoxVizFieldOfView``, which RflySim ignores)::

    {"shape": "ellipse", "half_width_deg": [35.2, 38.6]}
    {"shape": "outline", "outline_deg": [[x, y], ...]}
    {"shape": "band", "elevation_deg": [-7.2, 52.2]}
    {"shape": "cone", "half_angle_deg": 19.2}
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from livox_viz.core.errors import ConfigError, quoted

PLANES: tuple[str, ...] = ("boresight", "panorama")
SHAPES: tuple[str, ...] = ("cone", "ellipse", "outline", "band")
FOV_KEY = "LivoxVizFieldOfView"
MAX_OUTLINE_VERTICES = 720
#: Envelope bins of a fitted outline (one vertex every degree around the boresight).
OUTLINE_BINS = 360
#: A table's envelope within this fraction of its largest radius everywhere is a cone.
ROUND_TOLERANCE = 0.01


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{FOV_KEY}.{name} = {quoted(value)}; allowed: a finite number")
    return float(value)


@dataclass(frozen=True)
class FieldOfView:
    """Where a sensor looks, in its pattern plane (degrees).

    Parameters
    ----------
    shape : {"cone", "ellipse", "outline", "band"}
    half_angle_deg : float
        ``cone``: the half-angle, in (0, 90).
    half_width_deg : tuple of 2 float
        ``ellipse``: half-extents along x and y, each in (0, 90].
    outline_deg : (n, 2) float64
        ``outline``: the polygon's vertices in order (3 to 720), each within 180 deg of the boresight.
    elevation_deg : tuple of 2 float
        ``band``: lowest and highest elevation, -90 <= low < high <= 90.
    """

    shape: str
    half_angle_deg: float = 0.0
    half_width_deg: tuple[float, float] = (0.0, 0.0)
    outline_deg: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)), compare=False, repr=False)
    elevation_deg: tuple[float, float] = (0.0, 0.0)
    _key: bytes = field(default=b"", repr=False, init=False)

    def __post_init__(self) -> None:
        if self.shape not in SHAPES:
            raise ConfigError(f"{FOV_KEY}.shape = {quoted(self.shape)}; allowed: {', '.join(SHAPES)}")
        outline = np.zeros((0, 2))
        if self.shape == "cone":
            radius = _number("half_angle_deg", self.half_angle_deg)
            if not 0 < radius < 90:
                raise ConfigError(f"{FOV_KEY}.half_angle_deg = {quoted(radius)}; allowed: (0, 90)")
            object.__setattr__(self, "half_angle_deg", radius)
        elif self.shape == "ellipse":
            widths = tuple(_number("half_width_deg", v) for v in self.half_width_deg)
            if len(widths) != 2 or not all(0 < v <= 90 for v in widths):
                raise ConfigError(f"{FOV_KEY}.half_width_deg = {quoted(list(widths))}; allowed: 2 numbers in (0, 90]")
            object.__setattr__(self, "half_width_deg", widths)
        elif self.shape == "outline":
            try:
                outline = np.array(self.outline_deg, dtype=np.float64)
            except (TypeError, ValueError):
                raise ConfigError(f"{FOV_KEY}.outline_deg; allowed: a list of [x, y] numbers") from None
            if outline.ndim != 2 or outline.shape[1] != 2 or not 3 <= outline.shape[0] <= MAX_OUTLINE_VERTICES:
                raise ConfigError(f"{FOV_KEY}.outline_deg has shape {outline.shape}; allowed: 3 to "
                                  f"{MAX_OUTLINE_VERTICES} [x, y] vertices")
            if not np.all(np.isfinite(outline)) or np.hypot(outline[:, 0], outline[:, 1]).max() > 180:
                raise ConfigError(f"{FOV_KEY}.outline_deg; allowed: finite vertices within 180 deg of the boresight")
            if _polygon_area(outline) == 0:
                raise ConfigError(f"{FOV_KEY}.outline_deg encloses no area; allowed: a polygon")
        else:
            low, high = (_number("elevation_deg", v) for v in self.elevation_deg)
            if not -90 <= low < high <= 90:
                raise ConfigError(f"{FOV_KEY}.elevation_deg = {quoted([low, high])}; allowed: -90 <= low < high <= 90")
            object.__setattr__(self, "elevation_deg", (low, high))
        outline.setflags(write=False)
        object.__setattr__(self, "outline_deg", outline)
        object.__setattr__(self, "_key", outline.tobytes())

    # Constructors -------------------------------------------------------------------------
    @classmethod
    def cone(cls, half_angle_deg: float) -> FieldOfView:
        """A circle of ``half_angle_deg`` around the boresight."""
        return cls("cone", half_angle_deg=half_angle_deg)

    @classmethod
    def ellipse(cls, width_deg: float, height_deg: float) -> FieldOfView:
        """An ellipse of full widths ``width_deg`` (x) by ``height_deg`` (y), e.g. the Avia's 70.4 x 77.2."""
        return cls("ellipse", half_width_deg=(width_deg / 2.0, height_deg / 2.0))

    @classmethod
    def band(cls, low_deg: float, high_deg: float) -> FieldOfView:
        """All of the horizon between two elevations (panorama plane)."""
        return cls("band", elevation_deg=(low_deg, high_deg))

    @classmethod
    def outline(cls, vertices_deg: np.ndarray) -> FieldOfView:
        """A polygon in the boresight plane."""
        return cls("outline", outline_deg=np.asarray(vertices_deg, dtype=np.float64))

    @classmethod
    def of_points(cls, xy_deg: np.ndarray, plane: str = "boresight") -> FieldOfView:
        """The field of view a scan's points fill: a band (panorama), a cone when round, else their envelope.

        Parameters
        ----------
        xy_deg : (n, 2) float64
            Pattern angles in ``plane``, degrees.
        plane : {"boresight", "panorama"}
        """
        xy = np.asarray(xy_deg, dtype=np.float64)
        if plane == "panorama":
            return cls.band(max(-90.0, float(xy[:, 1].min())), min(90.0, float(xy[:, 1].max())))
        radius = np.hypot(xy[:, 0], xy[:, 1])
        reach = float(radius.max())
        if reach <= 0:
            raise ConfigError("the points all lie on the boresight; they span no field of view")
        bins = np.clip(((np.arctan2(xy[:, 1], xy[:, 0]) + math.pi) / (2 * math.pi) * OUTLINE_BINS).astype(np.int64),
                       0, OUTLINE_BINS - 1)
        # The farthest point of each bin of polar angle is a vertex: the outline passes through real points.
        order = np.lexsort((radius, bins))
        last = np.flatnonzero(np.diff(bins[order], append=OUTLINE_BINS))
        farthest = order[last]
        if radius[farthest].min() >= (1 - ROUND_TOLERANCE) * reach and farthest.size == OUTLINE_BINS:
            return cls.cone(min(reach, 89.999))
        return cls.outline(xy[farthest])

    # What it is ---------------------------------------------------------------------------
    @property
    def plane(self) -> str:
        """The pattern plane: ``"panorama"`` for a band, ``"boresight"`` otherwise."""
        return "panorama" if self.shape == "band" else "boresight"

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) degrees: the smallest box holding the field of view."""
        if self.shape == "cone":
            r = self.half_angle_deg
            return (-r, r, -r, r)
        if self.shape == "ellipse":
            a, b = self.half_width_deg
            return (-a, a, -b, b)
        if self.shape == "outline":
            v = self.outline_deg
            return (float(v[:, 0].min()), float(v[:, 0].max()), float(v[:, 1].min()), float(v[:, 1].max()))
        return (-180.0, 180.0, *self.elevation_deg)

    @property
    def reach_deg(self) -> float:
        """The largest angle off the boresight inside (boresight plane); 180 for a band."""
        if self.shape == "cone":
            return self.half_angle_deg
        if self.shape == "ellipse":
            return max(self.half_width_deg)
        if self.shape == "outline":
            return float(np.hypot(self.outline_deg[:, 0], self.outline_deg[:, 1]).max())
        return 180.0

    @property
    def size_deg(self) -> tuple[float, float]:
        """Full width and height, degrees (the figures a specification sheet gives)."""
        x0, x1, y0, y1 = self.bounds
        return (x1 - x0, y1 - y0)

    def describe(self) -> str:
        """One line, e.g. ``"cone of half-angle 19.17 deg"``."""
        width, height = self.size_deg
        if self.shape == "cone":
            return f"cone of half-angle {self.half_angle_deg:.4g} deg"
        if self.shape == "ellipse":
            return f"ellipse {width:.4g} x {height:.4g} deg"
        if self.shape == "outline":
            return f"outline {width:.4g} x {height:.4g} deg ({self.outline_deg.shape[0]} vertices)"
        low, high = self.elevation_deg
        return f"360 deg band, elevation {low:.4g} to {high:.4g} deg"

    def profile(self, xy_deg: np.ndarray) -> np.ndarray:
        """``(n,)`` the coordinate the density profile runs along: angle off the boresight, or elevation."""
        xy = np.asarray(xy_deg, dtype=np.float64)
        if self.plane == "panorama":
            return xy[:, 1].copy()
        return np.hypot(xy[:, 0], xy[:, 1])

    @property
    def profile_range(self) -> tuple[float, float]:
        """The span of :meth:`profile` inside, degrees."""
        if self.plane == "panorama":
            return self.elevation_deg
        return (0.0, self.reach_deg)

    @property
    def profile_label(self) -> str:
        """What :meth:`profile` measures, for chart axes."""
        return "elevation, deg" if self.plane == "panorama" else "angle off the boresight, deg"

    def contains(self, xy_deg: np.ndarray) -> np.ndarray:
        """``(n,)`` bool: which points lie inside.

        Parameters
        ----------
        xy_deg : (n, 2) float64
        """
        xy = np.asarray(xy_deg, dtype=np.float64)
        x, y = xy[:, 0], xy[:, 1]
        if self.shape == "cone":
            return np.hypot(x, y) <= self.half_angle_deg
        if self.shape == "ellipse":
            a, b = self.half_width_deg
            return (x / a) ** 2 + (y / b) ** 2 <= 1.0
        if self.shape == "band":
            low, high = self.elevation_deg
            return (y >= low) & (y <= high) & (x >= -180.0) & (x <= 180.0)
        return _inside_polygon(self.outline_deg, x, y)

    def grid_inside(self, x_centres: np.ndarray, y_centres: np.ndarray) -> np.ndarray:
        """``(nx, ny)`` bool: which cells of a grid have their centre inside (a polygon row by row).

        Parameters
        ----------
        x_centres : (nx,) float64
        y_centres : (ny,) float64
        """
        if self.shape != "outline":
            gx, gy = np.meshgrid(x_centres, y_centres, indexing="ij")
            return self.contains(np.column_stack([gx.ravel(), gy.ravel()])).reshape(gx.shape)
        x0, y0 = self.outline_deg[:, 0], self.outline_deg[:, 1]
        x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
        mask = np.zeros((x_centres.size, y_centres.size), dtype=bool)
        for j, y in enumerate(y_centres):
            crosses = (y0 > y) != (y1 > y)
            at = np.sort(x0[crosses] + (y - y0[crosses]) * (x1[crosses] - x0[crosses]) / (y1[crosses] - y0[crosses]))
            mask[:, j] = np.searchsorted(at, x_centres, side="right") % 2 == 1
        return mask

    def cell_solid_angle(self, x_deg: np.ndarray, y_deg: np.ndarray, cell_x_deg: float,
                         cell_y_deg: float) -> np.ndarray:
        """Solid angle of small cells centred at (x, y) of the plane, steradians.

        The boresight plane is azimuthal-equidistant (an area element is
        ``sin(alpha) / alpha dx dy``); the panorama plane is equirectangular
        (``cos(elevation) dx dy``).
        """
        area = math.radians(cell_x_deg) * math.radians(cell_y_deg)
        if self.plane == "panorama":
            return area * np.cos(np.radians(y_deg))
        alpha = np.radians(np.hypot(x_deg, y_deg))
        return area * np.sinc(alpha / np.pi)

    def boundary(self, vertices: int = 180) -> np.ndarray:
        """``(n, 2)`` the outline as a closed polyline (first vertex repeated last), for drawing.

        A band is the rectangle between its elevations from azimuth -180 to 180.
        """
        if self.shape == "band":
            low, high = self.elevation_deg
            return np.array([[-180.0, low], [180.0, low], [180.0, high], [-180.0, high], [-180.0, low]])
        if self.shape == "outline":
            return np.vstack([self.outline_deg, self.outline_deg[:1]])
        angle = np.linspace(0.0, 2 * math.pi, vertices + 1)
        a, b = (self.half_angle_deg,) * 2 if self.shape == "cone" else self.half_width_deg
        return np.column_stack([a * np.cos(angle), b * np.sin(angle)])

    @cached_property
    def solid_angle_sr(self) -> float:
        """The solid angle inside, steradians."""
        if self.shape == "cone":
            return 2 * math.pi * (1 - math.cos(math.radians(self.half_angle_deg)))
        if self.shape == "band":
            low, high = np.radians(self.elevation_deg)
            return 2 * math.pi * float(math.sin(high) - math.sin(low))
        x0, x1, y0, y1 = self.bounds
        step = max(x1 - x0, y1 - y0) / 800
        xs = np.arange(x0 + step / 2, x1, step)
        ys = np.arange(y0 + step / 2, y1, step)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        inside = self.grid_inside(xs, ys)
        return float(self.cell_solid_angle(gx[inside], gy[inside], step, step).sum())

    # JSON -----------------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The ``LivoxVizFieldOfView`` object."""
        if self.shape == "cone":
            return {"shape": "cone", "half_angle_deg": self.half_angle_deg}
        if self.shape == "ellipse":
            return {"shape": "ellipse", "half_width_deg": list(self.half_width_deg)}
        if self.shape == "band":
            return {"shape": "band", "elevation_deg": list(self.elevation_deg)}
        return {"shape": "outline", "outline_deg": [[round(float(x), 4), round(float(y), 4)]
                                                    for x, y in self.outline_deg]}

    @classmethod
    def from_json(cls, data: Any) -> FieldOfView:
        """Read the ``LivoxVizFieldOfView`` object; a :class:`ConfigError` names the bad key."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{FOV_KEY} must be a JSON object, got {type(data).__name__}")
        shape = data.get("shape")
        needs = {"cone": "half_angle_deg", "ellipse": "half_width_deg", "outline": "outline_deg",
                 "band": "elevation_deg"}
        if shape not in needs:
            raise ConfigError(f"{FOV_KEY}.shape = {quoted(shape)}; allowed: {', '.join(SHAPES)}")
        key = needs[shape]
        if key not in data:
            raise ConfigError(f"{FOV_KEY}: a {shape} needs {quoted(key)}")
        value = data[key]
        if shape in ("ellipse", "band") and (not isinstance(value, list) or len(value) != 2):
            raise ConfigError(f"{FOV_KEY}.{key} = {quoted(value)}; allowed: a list of 2 numbers")
        if shape == "outline" and not isinstance(value, list):
            raise ConfigError(f"{FOV_KEY}.outline_deg; allowed: a list of [x, y] vertices")
        return cls(shape, **{key: tuple(value) if shape in ("ellipse", "band") else value})


def _polygon_area(vertices: np.ndarray) -> float:
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))


def _inside_polygon(vertices: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Even-odd rule: a point is inside when a ray to +x crosses the edges an odd number of times."""
    inside = np.zeros(x.shape, dtype=bool)
    x0, y0 = vertices[:, 0], vertices[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    for ax, ay, bx, by in zip(x0, y0, x1, y1, strict=True):
        if ay == by:
            continue
        crosses = (ay > y) != (by > y)
        at = ax + (y - ay) * (bx - ax) / (by - ay)
        inside ^= crosses & (x < at)
    return inside
