"""A view's camera as data, and the arithmetic of orthographic (parallel) projection, without VTK.

:class:`CameraState` is the one form a camera is written in: a screenshot's
sidecar holds one per view and a saved viewpoint (View > Viewpoints) holds
the scene view's, both as :meth:`CameraState.to_json` writes it. The
functions below are what the scene view's projection switch and its
orthographic reset compute; a camera object is touched only by
:meth:`CameraState.of` and :meth:`CameraState.apply` (any object with
pyvista's ``Camera`` attributes).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from livox_viz.core.errors import LivoxVizError

#: The keys of a camera as it is written, in order (a sidecar's and a viewpoint's).
CAMERA_KEYS = ("position", "focal_point", "up", "parallel_scale", "view_angle", "parallel")
#: The projections a user picks between (View > Projection).
PROJECTIONS = ("perspective", "orthographic")


@dataclass(frozen=True)
class CameraState:
    """Where a camera is and how it projects.

    Parameters
    ----------
    position, focal_point : tuple of 3 float
        The eye and the point it looks at, in the view's world coordinates (metres in the scene view, degrees
        in the pattern view).
    up : tuple of 3 float
        The view's up direction (any length but zero; not along the line of sight).
    parallel_scale : float
        Half the height the view shows when orthographic, in the world's units (> 0).
    view_angle : float
        The vertical angle the view shows when perspective, degrees (0 to 180, both excluded).
    parallel : bool
        Orthographic (parallel) projection, else perspective.
    """

    position: tuple[float, float, float]
    focal_point: tuple[float, float, float]
    up: tuple[float, float, float]
    parallel_scale: float
    view_angle: float
    parallel: bool

    def __post_init__(self) -> None:
        for key in ("position", "focal_point", "up"):
            value = getattr(self, key)
            if len(value) != 3 or not all(math.isfinite(v) for v in value):
                raise LivoxVizError(f"camera {key} {list(value)}; allowed: three finite numbers")
        sight = np.subtract(self.focal_point, self.position)
        if not np.linalg.norm(sight) > 0:
            raise LivoxVizError("camera position equals its focal point; allowed: an eye apart from what it looks at")
        up = np.asarray(self.up, dtype=float)
        if np.linalg.norm(np.cross(sight, up)) <= 1e-9 * np.linalg.norm(sight) * max(np.linalg.norm(up), 1e-300):
            raise LivoxVizError(f"camera up {list(self.up)} is zero or along the line of sight; allowed: a "
                                "direction across it")
        if not (math.isfinite(self.parallel_scale) and self.parallel_scale > 0):
            raise LivoxVizError(f"camera parallel_scale {self.parallel_scale!r}; allowed: a number > 0")
        if not (math.isfinite(self.view_angle) and 0 < self.view_angle < 180):
            raise LivoxVizError(f"camera view_angle {self.view_angle!r} deg; allowed: between 0 and 180 deg")

    @classmethod
    def from_json(cls, data: Any, what: str = "camera") -> CameraState:
        """The camera a JSON object holds (:meth:`to_json`'s keys, all of them).

        Raises
        ------
        LivoxVizError
            One line naming ``what``, the key and what is allowed.
        """
        if not isinstance(data, Mapping):
            raise LivoxVizError(f"{what}: {type(data).__name__} instead of an object; allowed: an object with "
                                f"{', '.join(CAMERA_KEYS)}")
        missing = [key for key in CAMERA_KEYS if key not in data]
        if missing:
            raise LivoxVizError(f"{what}: no {', '.join(missing)}; allowed: an object with {', '.join(CAMERA_KEYS)}")
        values: dict[str, Any] = {}
        for key in ("position", "focal_point", "up"):
            given = data[key]
            if not (isinstance(given, list | tuple) and len(given) == 3 and all(_is_number(v) for v in given)):
                raise LivoxVizError(f"{what}: {key} {given!r}; allowed: a list of three numbers")
            values[key] = tuple(float(v) for v in given)
        for key in ("parallel_scale", "view_angle"):
            if not _is_number(data[key]):
                raise LivoxVizError(f"{what}: {key} {data[key]!r}; allowed: a number")
            values[key] = float(data[key])
        if not isinstance(data["parallel"], bool):
            raise LivoxVizError(f"{what}: parallel {data['parallel']!r}; allowed: true or false")
        try:
            return cls(parallel=data["parallel"], **values)
        except LivoxVizError as exc:
            raise LivoxVizError(f"{what}: {str(exc).removeprefix('camera ')}") from None

    def to_json(self) -> dict[str, Any]:
        """The camera as a JSON object (the sidecar's and the viewpoints file's form)."""
        return {"position": list(self.position), "focal_point": list(self.focal_point), "up": list(self.up),
                "parallel_scale": self.parallel_scale, "view_angle": self.view_angle, "parallel": self.parallel}

    @classmethod
    def of(cls, camera: Any) -> CameraState:
        """The state of a pyvista camera."""
        return cls(position=tuple(camera.position), focal_point=tuple(camera.focal_point), up=tuple(camera.up),
                   parallel_scale=float(camera.parallel_scale), view_angle=float(camera.view_angle),
                   parallel=bool(camera.parallel_projection))

    def apply(self, camera: Any) -> None:
        """Put a pyvista camera in this state (its renderer's clipping range is the caller's to reset)."""
        if self.parallel:
            camera.enable_parallel_projection()
        else:
            camera.disable_parallel_projection()
        camera.position = self.position
        camera.focal_point = self.focal_point
        camera.up = self.up
        camera.parallel_scale = self.parallel_scale
        camera.view_angle = self.view_angle

    @property
    def projection(self) -> str:
        """``"orthographic"`` or ``"perspective"``."""
        return PROJECTIONS[1] if self.parallel else PROJECTIONS[0]


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def parallel_scale_for(distance: float, view_angle_deg: float) -> float:
    """The parallel scale (half the view's height) at which an orthographic view shows what a perspective view of
    vertical angle ``view_angle_deg`` degrees shows at ``distance`` from its eye (its focal point's plane): the
    switch to orthographic keeps what is looked at the same size."""
    return distance * math.tan(math.radians(view_angle_deg) / 2)


def distance_for(parallel_scale: float, view_angle_deg: float) -> float:
    """The inverse of :func:`parallel_scale_for`: how far from its focal point a perspective eye of vertical angle
    ``view_angle_deg`` degrees shows the focal plane as an orthographic view of ``parallel_scale`` does."""
    return parallel_scale / math.tan(math.radians(view_angle_deg) / 2)


def screen_axes(direction: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(right, screen_up, forward)``, unit vectors of a camera looking along ``direction`` with ``up`` roughly
    up (its component across the line of sight is the screen's up)."""
    forward = np.asarray(direction, dtype=float)
    forward = forward / np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(up, dtype=float))
    right /= np.linalg.norm(right)
    return right, np.cross(right, forward), forward


def fit_parallel(points: np.ndarray, direction: np.ndarray, up: np.ndarray, aspect: float,
                 free_width: float = 1.0, free_height: float = 1.0, margin: float = 1.0) -> tuple[np.ndarray, float]:
    """The focal point and parallel scale of an orthographic camera looking along ``direction`` that draws every
    one of ``points`` inside the part of the view left free by a strip on its right and a band at its top, with
    the points' middle in that part's middle.

    Parameters
    ----------
    points : (n, 3) float
        What must be in view, world coordinates (n >= 1).
    direction, up : (3,) float
        The line of sight and the view's up (not along it).
    aspect : float
        The view's width over its height, pixels.
    free_width, free_height : float
        The shares of the view's width (from its left) and height (from its bottom) the points may take, 0 to 1.
    margin : float
        The share of that part the points' extent fills at most (0 to 1).

    Returns
    -------
    focal_point : (3,) float
        At the points' middle along the line of sight too.
    parallel_scale : float
        Half the view's height, world units.
    """
    right, screen_up, forward = screen_axes(direction, up)
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    x, y, z = points @ right, points @ screen_up, points @ forward
    width, height = float(np.ptp(x)), float(np.ptp(y))
    scale = max(height / (2 * free_height * margin), width / (2 * aspect * free_width * margin), 1e-3)
    # Moved right and up by half of what the strip and the band take, the camera draws the points' middle in the
    # middle of the free part.
    across = (x.min() + x.max()) / 2 + scale * aspect * (1 - free_width)
    upward = (y.min() + y.max()) / 2 + scale * (1 - free_height)
    return right * across + screen_up * upward + forward * (z.min() + z.max()) / 2, scale
