"""The parameters of the Risley-prism pattern model (``risley.md``), as a validated frozen value.

The track of laser k is a finite series of rotating vectors (degrees, pattern
plane, z = x + iy):

    z_k(t) = sum_j  c_{k,j} exp(i (m_j A(t) + l_j B(t))),
    A(t) = 2 pi f_A t + a0,   B(t) = 2 pi f_B t + b0.

The phases a0, b0 are chosen so that laser 0's own prism terms (1, 0) and
(0, 1) are real and positive: those two coefficients are the prisms'
deflections.

**What the sliders move.** A user tunes the two prism speeds (rpm = 60 f),
the two deflections and the lasers' spacing. The series keeps its fitted
coefficients ``c0`` and scales them: with s_A = deflection_A / deflection_A0
and s_B likewise, term (m, l) is multiplied by ``s_A**|m| * s_B**|l|`` (the
order of a refraction term in each prism's wedge: the prism terms scale
linearly, the third-order terms (2, -1) and (-1, 2) as s_A**2 s_B and
s_A s_B**2, and so on). The lasers' spacing ``g`` scales every laser's
difference from the mean of all lasers: c_k = mean + g (c0_k - mean).

JSON (livox-viz's own key ``LivoxVizRisley``, which RflySim ignores)::

    {"prism_hz": [77.7333, -121.5667], "phase_rad": [a0, b0],
     "terms": [[1, 0], [0, 1], ...], "coefficients_deg": [[[re, im], ...], ...],
     "deflection_deg": [9.54, 9.71], "laser_spacing": 1.0}
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from livox_viz.core.errors import ConfigError, quoted

MAX_LASERS = 64
MAX_TERMS = 64
MAX_PRISM_HZ = 1000.0
#: The smallest prism deflection a Risley track may be fitted with (its sliders divide by it), degrees.
MIN_DEFLECTION_DEG = 1e-3
#: The furthest a Risley track may reach from the boresight, degrees (the boresight plane ends at 180).
MAX_REACH_DEG = 180.0


def _finite(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"LivoxVizRisley.{name} = {quoted(value)}; allowed: a finite number")
    return float(value)


@dataclass(frozen=True)
class RisleyParams:
    """A Risley-prism track: prism frequencies and phases, series terms, per-laser coefficients.

    Parameters
    ----------
    prism_hz : tuple of 2 float
        f_A, f_B, revolutions per second, signed (opposite senses have opposite signs).
    phase_rad : tuple of 2 float
        a0, b0, radians.
    terms : tuple of (int, int)
        (m_j, l_j) of each term.
    base_coefficients : (K, J) complex128
        c0_{k,j}, degrees: the series as fitted (K lasers, J terms).
    deflection_deg : tuple of 2 float
        The prisms' deflections the user chose, degrees (default: the fitted ones).
    laser_spacing : float
        Scale of each laser's difference from the mean laser (1 = as fitted).
    """

    prism_hz: tuple[float, float]
    phase_rad: tuple[float, float]
    terms: tuple[tuple[int, int], ...]
    base_coefficients: np.ndarray = field(repr=False, compare=False)
    deflection_deg: tuple[float, float] | None = None
    laser_spacing: float = 1.0
    _key: bytes = field(default=b"", repr=False, init=False)

    def __post_init__(self) -> None:
        hz = tuple(_finite("prism_hz", v) for v in self.prism_hz)
        if len(hz) != 2 or any(abs(v) > MAX_PRISM_HZ for v in hz):
            raise ConfigError(f"LivoxVizRisley.prism_hz = {quoted(list(self.prism_hz))}; allowed: 2 numbers in "
                              f"[-{MAX_PRISM_HZ:g}, {MAX_PRISM_HZ:g}] Hz")
        phases = tuple(_finite("phase_rad", v) for v in self.phase_rad)
        if len(phases) != 2:
            raise ConfigError("LivoxVizRisley.phase_rad; allowed: 2 numbers (radians)")
        terms = tuple((int(m), int(n)) for m, n in self.terms)
        if not 1 <= len(terms) <= MAX_TERMS or len(set(terms)) != len(terms):
            raise ConfigError(f"LivoxVizRisley.terms has {len(terms)} entries; allowed: 1 to {MAX_TERMS} distinct "
                              "[m, l] pairs")
        if any(max(abs(m), abs(n)) > 32 for m, n in terms):
            raise ConfigError("LivoxVizRisley.terms; allowed: |m|, |l| <= 32")
        coefficients = np.asarray(self.base_coefficients, dtype=np.complex128)
        shape_ok = coefficients.ndim == 2 and coefficients.shape[1] == len(terms)
        if not shape_ok or not 1 <= coefficients.shape[0] <= MAX_LASERS:
            raise ConfigError(f"LivoxVizRisley.coefficients_deg has shape {coefficients.shape}; allowed: "
                              f"(lasers 1..{MAX_LASERS}, {len(terms)} terms)")
        if not np.all(np.isfinite(coefficients)):
            raise ConfigError("LivoxVizRisley.coefficients_deg holds NaN or infinite values; allowed: finite numbers")
        if (1, 0) not in terms or (0, 1) not in terms:
            raise ConfigError("LivoxVizRisley.terms must hold the prism terms [1, 0] and [0, 1]")
        base = self.base_deflection_deg(coefficients, terms)
        if not all(MIN_DEFLECTION_DEG <= v <= 45 for v in base):
            raise ConfigError(f"LivoxVizRisley: laser 0's prism terms [1, 0] and [0, 1] are {base[0]:.4g} and "
                              f"{base[1]:.4g} deg; allowed: deflections in [{MIN_DEFLECTION_DEG:g}, 45] deg")
        deflection = base if self.deflection_deg is None else tuple(
            _finite("deflection_deg", v) for v in self.deflection_deg)
        if len(deflection) != 2 or not all(0 < v <= 45 for v in deflection):
            raise ConfigError(f"LivoxVizRisley.deflection_deg = {quoted(list(deflection))}; allowed: 2 numbers in "
                              "(0, 45]")
        spacing = _finite("laser_spacing", self.laser_spacing)
        if not 0 <= spacing <= 10:
            raise ConfigError(f"LivoxVizRisley.laser_spacing = {quoted(spacing)}; allowed: [0, 10]")
        coefficients.setflags(write=False)
        object.__setattr__(self, "prism_hz", hz)
        object.__setattr__(self, "phase_rad", phases)
        object.__setattr__(self, "terms", terms)
        object.__setattr__(self, "base_coefficients", coefficients)
        object.__setattr__(self, "deflection_deg", deflection)
        object.__setattr__(self, "laser_spacing", spacing)
        # Equality and hashing by value, coefficients included.
        object.__setattr__(self, "_key", coefficients.tobytes())
        # The series as the sliders scale it must stay a direction: finite, within 180 deg of the boresight.
        reach = np.abs(self.coefficients).sum(axis=1)
        if not np.all(np.isfinite(reach)) or reach.max() > MAX_REACH_DEG:
            laser = int(np.argmax(np.nan_to_num(reach, nan=np.inf)))
            raise ConfigError(f"LivoxVizRisley: laser {laser}'s terms add up to {reach[laser]:.4g} deg; allowed: at "
                              f"most {MAX_REACH_DEG:g} deg off the boresight")

    @staticmethod
    def base_deflection_deg(coefficients: np.ndarray, terms: tuple[tuple[int, int], ...]) -> tuple[float, float]:
        """|c0_{0,(1,0)}| and |c0_{0,(0,1)}|: laser 0's fitted prism deflections, degrees."""
        return (float(abs(coefficients[0, terms.index((1, 0))])), float(abs(coefficients[0, terms.index((0, 1))])))

    @property
    def lasers(self) -> int:
        """K, lasers firing in turn."""
        return int(self.base_coefficients.shape[0])

    @property
    def prism_rpm(self) -> tuple[float, float]:
        """The prisms' speeds, revolutions per minute (signed)."""
        return (60.0 * self.prism_hz[0], 60.0 * self.prism_hz[1])

    @cached_property
    def coefficients(self) -> np.ndarray:
        """``(K, J)`` complex128 c_{k,j} in degrees after the deflection and spacing scaling."""
        base = self.base_coefficients
        fitted = self.base_deflection_deg(base, self.terms)
        scale_a = self.deflection_deg[0] / fitted[0]
        scale_b = self.deflection_deg[1] / fitted[1]
        orders = np.array(self.terms, dtype=np.float64).reshape(-1, 2)
        mean = base.mean(axis=0, keepdims=True)
        spread = mean + self.laser_spacing * (base - mean)
        # Extreme values overflow to inf here; validation refuses them with the reach they give.
        with np.errstate(over="ignore", invalid="ignore"):
            powers = np.power(scale_a, np.abs(orders[:, 0])) * np.power(scale_b, np.abs(orders[:, 1]))
            result = spread * powers[None, :]
        result.setflags(write=False)
        return result

    @property
    def term_hz(self) -> np.ndarray:
        """``(J,)`` float64 angular frequency of each term, revolutions per second: m f_A + l f_B."""
        return np.array([m * self.prism_hz[0] + n * self.prism_hz[1] for m, n in self.terms])

    @property
    def term_phase(self) -> np.ndarray:
        """``(J,)`` float64 phase of each term at t = 0, radians: m a0 + l b0."""
        return np.array([m * self.phase_rad[0] + n * self.phase_rad[1] for m, n in self.terms])

    def laser_spacing_deg(self) -> float:
        """Mean distance between neighbouring lasers' series centres (their constant terms), degrees; 0 for one."""
        if self.lasers < 2:
            return 0.0
        centre = self.coefficients[:, self.terms.index((0, 0))] if (0, 0) in self.terms else np.zeros(self.lasers)
        return float(np.abs(np.diff(centre)).mean())

    # JSON ---------------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The ``LivoxVizRisley`` object."""
        return {
            "prism_hz": [round(v, 9) for v in self.prism_hz],
            "phase_rad": [round(v, 12) for v in self.phase_rad],
            "terms": [[m, n] for m, n in self.terms],
            "coefficients_deg": [[[float(c.real), float(c.imag)] for c in laser] for laser in self.base_coefficients],
            "deflection_deg": [float(v) for v in self.deflection_deg],
            "laser_spacing": self.laser_spacing,
        }

    @classmethod
    def from_json(cls, data: Any) -> RisleyParams:
        """Read the ``LivoxVizRisley`` object; a :class:`ConfigError` names the bad key."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"LivoxVizRisley must be a JSON object, got {type(data).__name__}")
        for key in ("prism_hz", "phase_rad", "terms", "coefficients_deg"):
            if key not in data:
                raise ConfigError(f"LivoxVizRisley: missing key {quoted(key)}; it needs prism_hz, phase_rad, terms, "
                                  "coefficients_deg")
        terms = data["terms"]
        if not isinstance(terms, list) or not all(
                isinstance(t, list) and len(t) == 2 and all(isinstance(v, int) and not isinstance(v, bool) for v in t)
                for t in terms):
            raise ConfigError("LivoxVizRisley.terms; allowed: a list of [m, l] integer pairs")
        try:
            raw = np.asarray(data["coefficients_deg"], dtype=np.float64)
        except (TypeError, ValueError):
            raise ConfigError("LivoxVizRisley.coefficients_deg; allowed: [lasers][terms][re, im] numbers") from None
        if raw.ndim != 3 or raw.shape[2] != 2:
            raise ConfigError(f"LivoxVizRisley.coefficients_deg has shape {raw.shape}; allowed: (lasers, terms, 2)")
        for key in ("prism_hz", "phase_rad"):
            if not isinstance(data[key], list) or len(data[key]) != 2:
                raise ConfigError(f"LivoxVizRisley.{key} = {quoted(data[key])}; allowed: a list of 2 numbers")
        deflection = data.get("deflection_deg")
        if deflection is not None and (not isinstance(deflection, list) or len(deflection) != 2):
            raise ConfigError(f"LivoxVizRisley.deflection_deg = {quoted(deflection)}; allowed: a list of 2 numbers")
        return cls(
            prism_hz=tuple(data["prism_hz"]),
            phase_rad=tuple(data["phase_rad"]),
            terms=tuple(tuple(t) for t in terms),
            base_coefficients=raw[..., 0] + 1j * raw[..., 1],
            deflection_deg=None if deflection is None else tuple(deflection),
            laser_spacing=data.get("laser_spacing", 1.0),
        )
