"""The parameters of the general track model: any Livox head as a two-frequency series, as a validated value.

Every Livox head steers its lasers with parts that turn or swing at two
steady rates, so each laser's direction is a function of two phases
A(t) = 2 pi f_A t + a0 and B(t) = 2 pi f_B t + b0, periodic in both, and
therefore a two-dimensional Fourier series (degrees, z = x + iy)::

    w_k(t) = sum_j  c_{k,j} exp(i (m_j A(t) + l_j B(t)))      (any integers m_j, l_j)

The Risley pair (``risley.md``) is the case m + l = 1 and its neighbours; an
oscillating part (the Horizon's, the HAP's) puts lines at +f and -f, so both
signs of an order appear. Two forms:

- ``"plane"``: the pattern point is w itself (boresight plane, or the panorama
  plane for a head that scans az/el without turning all the way round);
- ``"spin"``: for heads whose azimuth turns all the way round (Mid-360), in the
  panorama plane: azimuth = degrees(A(t)) + Re w (wrapped to [-180, 180)),
  elevation = Im w. The spin is base A.

JSON (livox-viz's own key ``LivoxVizTrack``, which RflySim ignores)::

    {"form": "plane", "base_hz": [122.533, 10.317], "phase_rad": [0, 0],
     "terms": [[1, 0], [-1, 0], [0, 1], ...], "coefficients_deg": [[[re, im], ...], ...]}
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from livox_viz.core.errors import ConfigError, quoted

TRACK_KEY = "LivoxVizTrack"
FORMS: tuple[str, ...] = ("plane", "spin")
MAX_LASERS = 64
MAX_TERMS = 512
MAX_ORDER = 64
MAX_BASE_HZ = 5000.0
#: The furthest a plane track may reach from the boresight (the boresight plane ends at 180 degrees).
MAX_PLANE_REACH_DEG = 180.0
#: The furthest a spin track's series may move the azimuth or the elevation.
MAX_SPIN_REACH_DEG = 360.0


def _finite(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{TRACK_KEY}.{name} = {quoted(value)}; allowed: a finite number")
    return float(value)


@dataclass(frozen=True)
class TrackParams:
    """A head's track: two base frequencies and phases, series terms, per-laser coefficients, a form.

    Parameters
    ----------
    form : {"plane", "spin"}
    base_hz : tuple of 2 float
        f_A, f_B, cycles per second, signed; |f| <= 5000. For ``"spin"`` f_A is the azimuth's turn rate.
    phase_rad : tuple of 2 float
        a0, b0, radians.
    terms : tuple of (int, int)
        (m_j, l_j) of each term, distinct, |m|, |l| <= 64.
    coefficients : (K, J) complex128
        c_{k,j}, degrees (K lasers firing in turn, J terms).
    """

    form: str
    base_hz: tuple[float, float]
    phase_rad: tuple[float, float]
    terms: tuple[tuple[int, int], ...]
    coefficients: np.ndarray = field(repr=False, compare=False)
    _key: bytes = field(default=b"", repr=False, init=False)

    def __post_init__(self) -> None:
        if self.form not in FORMS:
            raise ConfigError(f"{TRACK_KEY}.form = {quoted(self.form)}; allowed: {' or '.join(FORMS)}")
        hz = tuple(_finite("base_hz", v) for v in self.base_hz)
        if len(hz) != 2 or any(abs(v) > MAX_BASE_HZ for v in hz):
            raise ConfigError(f"{TRACK_KEY}.base_hz = {quoted(list(self.base_hz))}; allowed: 2 numbers in "
                              f"[-{MAX_BASE_HZ:g}, {MAX_BASE_HZ:g}] Hz")
        phases = tuple(_finite("phase_rad", v) for v in self.phase_rad)
        if len(phases) != 2 or any(abs(v) > 1e6 for v in phases):
            raise ConfigError(f"{TRACK_KEY}.phase_rad; allowed: 2 numbers in [-1e6, 1e6] radians")
        terms = tuple((int(m), int(n)) for m, n in self.terms)
        if not 1 <= len(terms) <= MAX_TERMS or len(set(terms)) != len(terms):
            raise ConfigError(f"{TRACK_KEY}.terms has {len(terms)} entries; allowed: 1 to {MAX_TERMS} distinct "
                              "[m, l] pairs")
        if any(max(abs(m), abs(n)) > MAX_ORDER for m, n in terms):
            raise ConfigError(f"{TRACK_KEY}.terms; allowed: |m|, |l| <= {MAX_ORDER}")
        coefficients = np.array(self.coefficients, dtype=np.complex128)
        shape_ok = coefficients.ndim == 2 and coefficients.shape[1] == len(terms)
        if not shape_ok or not 1 <= coefficients.shape[0] <= MAX_LASERS:
            raise ConfigError(f"{TRACK_KEY}.coefficients_deg has shape {coefficients.shape}; allowed: "
                              f"(lasers 1..{MAX_LASERS}, {len(terms)} terms)")
        if not np.all(np.isfinite(coefficients)):
            raise ConfigError(f"{TRACK_KEY}.coefficients_deg holds NaN or infinite values; allowed: finite numbers")
        limit = MAX_SPIN_REACH_DEG if self.form == "spin" else MAX_PLANE_REACH_DEG
        reach = np.abs(coefficients).sum(axis=1)
        if reach.max() > limit:
            laser = int(np.argmax(reach))
            raise ConfigError(f"{TRACK_KEY}.coefficients_deg: laser {laser}'s terms add up to {reach.max():.4g} deg; "
                              f"allowed: at most {limit:g} deg for a {self.form} track")
        coefficients.setflags(write=False)
        object.__setattr__(self, "base_hz", hz)
        object.__setattr__(self, "phase_rad", phases)
        object.__setattr__(self, "terms", terms)
        object.__setattr__(self, "coefficients", coefficients)
        object.__setattr__(self, "_key", coefficients.tobytes())

    @property
    def lasers(self) -> int:
        """K, lasers firing in turn."""
        return int(self.coefficients.shape[0])

    @property
    def term_hz(self) -> np.ndarray:
        """``(J,)`` float64 frequency of each term, cycles per second: m f_A + l f_B."""
        return np.array([m * self.base_hz[0] + n * self.base_hz[1] for m, n in self.terms], dtype=np.float64)

    @property
    def term_phase(self) -> np.ndarray:
        """``(J,)`` float64 phase of each term at t = 0, radians: m a0 + l b0."""
        return np.array([m * self.phase_rad[0] + n * self.phase_rad[1] for m, n in self.terms], dtype=np.float64)

    @property
    def spin_hz(self) -> float:
        """The azimuth's turn rate of a spin track (f_A), 0 for a plane track."""
        return self.base_hz[0] if self.form == "spin" else 0.0

    @property
    def base_rpm(self) -> tuple[float, float]:
        """The base frequencies as revolutions per minute (signed)."""
        return (60.0 * self.base_hz[0], 60.0 * self.base_hz[1])

    # JSON ---------------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The ``LivoxVizTrack`` object."""
        return {
            "form": self.form,
            "base_hz": [float(v) for v in self.base_hz],
            "phase_rad": [float(v) for v in self.phase_rad],
            "terms": [[m, n] for m, n in self.terms],
            "coefficients_deg": [[[float(c.real), float(c.imag)] for c in laser] for laser in self.coefficients],
        }

    @classmethod
    def from_json(cls, data: Any) -> TrackParams:
        """Read the ``LivoxVizTrack`` object; a :class:`ConfigError` names the bad key."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{TRACK_KEY} must be a JSON object, got {type(data).__name__}")
        for key in ("form", "base_hz", "phase_rad", "terms", "coefficients_deg"):
            if key not in data:
                raise ConfigError(f"{TRACK_KEY}: missing key {quoted(key)}; it needs form, base_hz, phase_rad, terms, "
                                  "coefficients_deg")
        terms = data["terms"]
        if not isinstance(terms, list) or not all(
                isinstance(t, list) and len(t) == 2 and all(isinstance(v, int) and not isinstance(v, bool) for v in t)
                for t in terms):
            raise ConfigError(f"{TRACK_KEY}.terms; allowed: a list of [m, l] integer pairs")
        try:
            raw = np.asarray(data["coefficients_deg"], dtype=np.float64)
        except (TypeError, ValueError):
            raise ConfigError(f"{TRACK_KEY}.coefficients_deg; allowed: [lasers][terms][re, im] numbers") from None
        if raw.ndim != 3 or raw.shape[2] != 2:
            raise ConfigError(f"{TRACK_KEY}.coefficients_deg has shape {raw.shape}; allowed: (lasers, terms, 2)")
        for key in ("base_hz", "phase_rad"):
            if not isinstance(data[key], list) or len(data[key]) != 2:
                raise ConfigError(f"{TRACK_KEY}.{key} = {quoted(data[key])}; allowed: a list of 2 numbers")
        return cls(form=data["form"], base_hz=tuple(data["base_hz"]), phase_rad=tuple(data["phase_rad"]),
                   terms=tuple(tuple(t) for t in terms), coefficients=raw[..., 0] + 1j * raw[..., 1])
