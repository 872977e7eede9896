"""A sensor's return model: what its datasheet says about the points it returns, as a validated frozen value.

A configuration carries it under ``"LivoxVizReturns"``, a key RflySim
ignores::

    "LivoxVizReturns": {
      "model": "datasheet",                            # or "ideal": the exact first hit, as RflySim computes
      "range_sigma_m": [[20, 0.02]],                   # (range m, 1-sigma m) pairs, linear between, flat outside
      "detection_range_m": [[0.1, 90], [0.8, 260]],    # (Lambertian reflectivity 0-1, range m) where P(detect) = 50 %
      "divergence_deg": [0.03, 0.28],                  # full beam divergence, horizontal (pattern x) x vertical (y)
      "blind_zone_m": 1.0,                             # nothing nearer is returned
      "false_alarm_rate": 0.0001,                      # a false point, per pulse that meets nothing
      "returns_per_pulse": 1,                          # 1 single, 2 dual, 3 triple
      "angular_sigma_deg": 0.0,                        # 1-sigma direction noise of a point
      "return0_range_m": 1.5,                          # a first return nearer than this is tagged return 0
      "return_separation_m": 0.6,                      # echoes nearer than this merge into one
      "detection_snr": 5.0                             # detection threshold / receiver noise (1 sigma)
    }

Every key but ``model`` may be left out and then takes the Livox Mid-70's value
(:data:`DATASHEETS` ``["mid70"]``).

**The lidar equation.** A beam's echo from a Lambertian surface of reflectance
rho, met at incidence theta and range r, carries the power

    P(r) ~ rho cos(theta) exp(-2 alpha r) / r^2

(the extended-target equation; ``exp(-2 alpha r)`` is the two-way loss along the
path). The detection threshold sits where the datasheet says a target of the
first listed reflectivity is detected half the time; with two figures, alpha is
chosen so the second one holds too (``(ln(rho_2/rho_1) - 2 ln(r_2/r_1)) / (2
(r_2 - r_1))``). It stands for the air's extinction and whatever else the sheet's
two figures say beyond 1/r^2: for the Mid-40/70's 90/260 m it comes out slightly
negative (-1.2e-4 per metre, a 6 % gain at 260 m), which is what those two
figures mean under this law; it is refused where the received power would no
longer fall with range.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from livox_viz.core.errors import ConfigError, quoted

RETURNS_KEY = "LivoxVizReturns"
#: "ideal": every ray's exact first hit, no noise, as RflySim computes it; "datasheet": the sheet's sensor.
RETURN_MODELS: tuple[str, ...] = ("ideal", "datasheet")
#: The datasheet the defaults come from (and that a configuration without a return model gets).
DEFAULT_SHEET = "mid70"


def _number(name: str, value: Any, low: float, high: float, low_open: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{RETURNS_KEY}.{name} = {quoted(value)}; allowed: a number in "
                          f"{'(' if low_open else '['}{low:g}, {high:g}]")
    value = float(value)
    if value > high or value < low or (low_open and value == low):
        raise ConfigError(f"{RETURNS_KEY}.{name} = {value:g} is out of range; allowed: "
                          f"{'(' if low_open else '['}{low:g}, {high:g}]")
    return value


def _pairs(name: str, value: Any, count: tuple[int, int], meaning: str) -> tuple[tuple[float, float], ...]:
    ok = isinstance(value, (list, tuple)) and count[0] <= len(value) <= count[1] and all(
        isinstance(p, (list, tuple)) and len(p) == 2 for p in value)
    if not ok:
        raise ConfigError(f"{RETURNS_KEY}.{name} = {quoted(value)}; allowed: {count[0]} to {count[1]} pairs "
                          f"[{meaning}]")
    return tuple((p[0], p[1]) for p in value)


@dataclass(frozen=True)
class ReturnParams:
    """What a sensor's datasheet says about its returns (see the module docstring for the JSON).

    Parameters
    ----------
    model : {"ideal", "datasheet"}
        Which model a scan uses by default (``--returns`` and the window's switch choose too).
    range_sigma_m : tuple of (float, float)
        (range m, 1-sigma range noise m) pairs, ranges increasing; linear in between, flat outside.
    detection_range_m : tuple of (float, float)
        One or two (Lambertian reflectivity 0-1, range m) pairs: the range where such a target at
        normal incidence is detected half the time.
    divergence_deg : (float, float)
        Full divergence of the beam, degrees: horizontal (pattern x) and vertical (pattern y).
    blind_zone_m : float
        No return nearer than this, metres.
    false_alarm_rate : float
        Probability that a pulse meeting nothing returns a false point.
    returns_per_pulse : int
        1 (single), 2 (dual) or 3 (triple return).
    angular_sigma_deg : float
        1-sigma noise of each point's direction, degrees (per axis).
    return0_range_m : float
        A first return nearer than this merges with the sensor's internal return 0 and is tagged so.
    return_separation_m : float
        Echoes of one pulse nearer to each other than this make one return.
    detection_snr : float
        Detection threshold over the receiver noise (1 sigma): sets how sharply P(detect) falls around
        the datasheet range.
    """

    model: str = "ideal"
    range_sigma_m: tuple[tuple[float, float], ...] = ((20.0, 0.02),)
    detection_range_m: tuple[tuple[float, float], ...] = ((0.1, 90.0), (0.8, 260.0))
    divergence_deg: tuple[float, float] = (0.03, 0.28)
    blind_zone_m: float = 0.05
    false_alarm_rate: float = 1e-4
    returns_per_pulse: int = 2
    angular_sigma_deg: float = 0.0
    return0_range_m: float = 1.5
    return_separation_m: float = 0.6
    detection_snr: float = 5.0

    def __post_init__(self) -> None:
        if self.model not in RETURN_MODELS:
            raise ConfigError(f"{RETURNS_KEY}.model = {quoted(self.model)}; allowed: {' or '.join(RETURN_MODELS)}")
        sigma = tuple((_number("range_sigma_m range", r, 0, 1e4), _number("range_sigma_m sigma", s, 0, 1))
                      for r, s in _pairs("range_sigma_m", self.range_sigma_m, (1, 16), "range m, sigma m"))
        if any(b[0] <= a[0] for a, b in itertools.pairwise(sigma)):
            raise ConfigError(f"{RETURNS_KEY}.range_sigma_m: the ranges must increase")
        # A sheet's figures: reflectivities of a few % up (1e-300 made every echo's byte 255), ranges of metres.
        detection = tuple((_number("detection_range_m reflectivity", p, 0.01, 1),
                           _number("detection_range_m range", r, 1, 1e5))
                          for p, r in _pairs("detection_range_m", self.detection_range_m, (1, 2),
                                             "reflectivity 0-1, range m"))
        if len(detection) == 2 and detection[0][0] == detection[1][0]:
            raise ConfigError(f"{RETURNS_KEY}.detection_range_m: two figures need two different reflectivities")
        divergence = self.divergence_deg
        if not isinstance(divergence, (list, tuple)) or len(divergence) != 2:
            raise ConfigError(f"{RETURNS_KEY}.divergence_deg = {quoted(divergence)}; allowed: [horizontal, vertical] "
                              "degrees")
        divergence = tuple(_number("divergence_deg", v, 0.001, 5) for v in divergence)  # the sliders' least
        returns = self.returns_per_pulse
        if isinstance(returns, bool) or returns not in (1, 2, 3):
            raise ConfigError(f"{RETURNS_KEY}.returns_per_pulse = {quoted(returns)}; allowed: 1, 2 or 3")
        object.__setattr__(self, "range_sigma_m", sigma)
        object.__setattr__(self, "detection_range_m", detection)
        object.__setattr__(self, "divergence_deg", divergence)
        object.__setattr__(self, "returns_per_pulse", int(returns))
        object.__setattr__(self, "blind_zone_m", _number("blind_zone_m", self.blind_zone_m, 0, 100))
        object.__setattr__(self, "false_alarm_rate", _number("false_alarm_rate", self.false_alarm_rate, 0, 0.01))
        object.__setattr__(self, "angular_sigma_deg", _number("angular_sigma_deg", self.angular_sigma_deg, 0, 1))
        object.__setattr__(self, "return0_range_m", _number("return0_range_m", self.return0_range_m, 0, 100))
        object.__setattr__(self, "return_separation_m",
                           _number("return_separation_m", self.return_separation_m, 0, 100, low_open=True))
        object.__setattr__(self, "detection_snr", _number("detection_snr", self.detection_snr, 1, 100))
        nearest = min(r for _, r in detection)
        if self.blind_zone_m > nearest:
            raise ConfigError(f"{RETURNS_KEY}.blind_zone_m = {self.blind_zone_m:g} m is beyond the sheet's detection "
                              f"range of {nearest:g} m (detection_range_m); allowed: a blind zone nearer than the "
                              "nearest detection range (the sheet's dimmest target would never be seen)")
        if len(detection) == 2:
            # First: two figures at one range would divide the loss's log-ratio by zero.
            if (detection[1][0] - detection[0][0]) * (detection[1][1] - detection[0][1]) <= 0:
                raise ConfigError(f"{RETURNS_KEY}.detection_range_m = {[list(p) for p in detection]}: the brighter "
                                  "target must reach farther; allowed: a larger range for the larger reflectivity")
            far = max(r for _, r in detection)
            if self.range_loss_per_m <= -1.0 / (2.0 * far):
                raise ConfigError(f"{RETURNS_KEY}.detection_range_m = {[list(p) for p in detection]}: under the lidar "
                                  "equation the received power would grow with range; allowed: figures where the "
                                  "brighter target reaches farther, by at most about its reflectivity ratio squared")

    # The lidar equation --------------------------------------------------------------------
    @property
    def range_loss_per_m(self) -> float:
        """alpha, the two-way loss coefficient per metre (0 with one detection figure)."""
        if len(self.detection_range_m) < 2:
            return 0.0
        (rho_a, r_a), (rho_b, r_b) = self.detection_range_m
        return (math.log(rho_b / rho_a) - 2.0 * math.log(r_b / r_a)) / (2.0 * (r_b - r_a))

    def signal_ratio(self, reflectance: np.ndarray, cos_incidence: np.ndarray, range_m: np.ndarray) -> np.ndarray:
        """Received power over the detection threshold: 1 where P(detect) is 50 %.

        Parameters
        ----------
        reflectance : (n,) float
            Lambertian reflectance (0-1; a retroreflector's is its gain times that).
        cos_incidence : (n,) float
            Cosine of the angle between the ray and the surface normal.
        range_m : (n,) float
            Metres.

        Returns
        -------
        ratio : (n,) float64
        """
        rho_a, r_a = self.detection_range_m[0]
        alpha = self.range_loss_per_m
        r = np.asarray(range_m, dtype=np.float64)
        ratio = np.asarray(reflectance) * np.asarray(cos_incidence) * (r_a * r_a / rho_a) / (r * r)
        return ratio if alpha == 0.0 else ratio * np.exp(-2.0 * alpha * (r - r_a))

    def power_to_reflectance(self, ratio: np.ndarray, range_m: np.ndarray) -> np.ndarray:
        """The Lambertian reflectance (at normal incidence) an echo of ``ratio`` at ``range_m`` metres implies."""
        rho_a, r_a = self.detection_range_m[0]
        r = np.asarray(range_m, dtype=np.float64)
        return np.asarray(ratio) * rho_a * (r / r_a) ** 2 * np.exp(2.0 * self.range_loss_per_m * (r - r_a))

    def detection_range(self, reflectivity: float) -> float:
        """Metres where a Lambertian target of ``reflectivity`` (0-1) at normal incidence is detected half the time."""
        rho_a, r_a = self.detection_range_m[0]
        alpha = self.range_loss_per_m
        target = math.log(rho_a) - 2.0 * alpha * r_a - 2.0 * math.log(r_a)
        low, high = 1e-3, 1e6
        for _ in range(200):  # bisection on log r: the power falls with range over the allowed parameters
            mid = math.sqrt(low * high)
            if math.log(reflectivity) - 2.0 * alpha * mid - 2.0 * math.log(mid) > target:
                low = mid
            else:
                high = mid
        return math.sqrt(low * high)

    def range_sigma(self, range_m: np.ndarray) -> np.ndarray:
        """1-sigma range noise at ``range_m`` metres, ``(n,)`` float64."""
        if len(self.range_sigma_m) == 1:
            return np.full(np.shape(range_m), self.range_sigma_m[0][1])
        table = np.asarray(self.range_sigma_m, dtype=np.float64)
        return np.interp(range_m, table[:, 0], table[:, 1])

    # Sliders -------------------------------------------------------------------------------
    def slider_value(self, name: str) -> float:
        """The value of one of :data:`RETURN_SLIDERS` (range noise and detection range as their first figures)."""
        if name == "range_sigma":
            return self.range_sigma_m[0][1]
        if name == "detection_range_10":
            return self.detection_range(0.1)
        if name == "divergence_h":
            return self.divergence_deg[0]
        if name == "divergence_v":
            return self.divergence_deg[1]
        return float(getattr(self, _SLIDER_FIELDS[name]))

    def with_slider(self, name: str, value: float) -> ReturnParams:
        """A copy with one slider moved; the range-noise and detection tables scale as a whole."""
        if name == "range_sigma":
            first = self.range_sigma_m[0][1]
            scale = value / first if first > 0 else None
            table = tuple((r, s * scale if scale is not None else value) for r, s in self.range_sigma_m)
            return replace(self, range_sigma_m=table)
        if name == "detection_range_10":
            scale = value / self.detection_range(0.1)
            return replace(self, detection_range_m=tuple((p, r * scale) for p, r in self.detection_range_m))
        if name == "divergence_h":
            return replace(self, divergence_deg=(value, self.divergence_deg[1]))
        if name == "divergence_v":
            return replace(self, divergence_deg=(self.divergence_deg[0], value))
        return replace(self, **{_SLIDER_FIELDS[name]: value})

    # JSON --------------------------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        """The ``LivoxVizReturns`` object."""
        return {
            "model": self.model,
            "range_sigma_m": [[_short(r), _short(s)] for r, s in self.range_sigma_m],
            "detection_range_m": [[_short(p), _short(r)] for p, r in self.detection_range_m],
            "divergence_deg": [_short(v) for v in self.divergence_deg],
            "blind_zone_m": _short(self.blind_zone_m),
            "false_alarm_rate": _short(self.false_alarm_rate),
            "returns_per_pulse": self.returns_per_pulse,
            "angular_sigma_deg": _short(self.angular_sigma_deg),
            "return0_range_m": _short(self.return0_range_m),
            "return_separation_m": _short(self.return_separation_m),
            "detection_snr": _short(self.detection_snr),
        }

    @classmethod
    def from_json(cls, data: Any) -> ReturnParams:
        """Read a ``LivoxVizReturns`` object; keys left out take the Mid-70's values; a bad key is named."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{RETURNS_KEY} must be a JSON object, got {type(data).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(f"{RETURNS_KEY}: unknown key {quoted(unknown[0])}; allowed: {', '.join(sorted(known))}")
        values = {key: (tuple(value) if isinstance(value, list) else value) for key, value in data.items()}
        return replace(DATASHEETS[DEFAULT_SHEET], **values)


def _short(value: float) -> int | float:
    return int(value) if float(value).is_integer() and abs(value) < 2**53 else float(value)


#: The return model's sliders: name -> (label with unit, low, high). The range noise's never reaches 0: it scales
#: the sheet's table as a whole (the Tele-15's 2 cm to 70 m, 4 cm at 120 m), and a table scaled to zero would come
#: back flat; 0.1 mm is far below the int16 encoding's step.
RETURN_SLIDERS: dict[str, tuple[str, float, float]] = {
    "range_sigma": ("range noise 1-sigma, m", 1e-4, 0.2),
    "detection_range_10": ("detection range at 10 % reflectivity, m", 1.0, 2000.0),
    "blind_zone": ("blind zone, m", 0.0, 10.0),
    "divergence_h": ("beam divergence, horizontal, deg", 0.001, 2.0),
    "divergence_v": ("beam divergence, vertical, deg", 0.001, 2.0),
    "false_alarm_rate": ("false alarms per empty pulse", 0.0, 0.01),
    "angular_sigma": ("angular noise 1-sigma, deg", 0.0, 0.5),
}
_SLIDER_FIELDS = {"blind_zone": "blind_zone_m", "false_alarm_rate": "false_alarm_rate",
                  "angular_sigma": "angular_sigma_deg"}


#: The public datasheets (Livox specification pages and wiki), as the issue tabulates them. Where a sheet
#: publishes no figure the value is chosen, and :data:`CHOSEN` says which.
DATASHEETS: dict[str, ReturnParams] = {
    "mid40": ReturnParams("datasheet", ((20.0, 0.02),), ((0.1, 90.0), (0.8, 260.0)), (0.03, 0.28), 1.0, 1e-4, 1),
    "mid70": ReturnParams("datasheet", ((20.0, 0.02),), ((0.1, 90.0), (0.8, 260.0)), (0.03, 0.28), 0.05, 1e-4, 2),
    "avia": ReturnParams("datasheet", ((20.0, 0.02),), ((0.1, 190.0), (0.8, 320.0)), (0.03, 0.28), 1.0, 1e-4, 3),
    "horizon": ReturnParams("datasheet", ((20.0, 0.02),), ((0.1, 90.0), (0.8, 260.0)), (0.03, 0.28), 0.5, 1e-4, 2),
    "tele15": ReturnParams("datasheet", ((70.0, 0.02), (120.0, 0.04)), ((0.1, 320.0), (0.5, 500.0)), (0.02, 0.12),
                           1.0, 1e-4, 2),
    "hap": ReturnParams("datasheet", ((20.0, 0.02),), ((0.1, 150.0),), (0.03, 0.28), 0.5, 1e-4, 1),
    "mid360": ReturnParams("datasheet", ((10.0, 0.02),), ((0.1, 40.0), (0.8, 70.0)), (0.1, 0.1), 0.1, 1e-4, 1),
}
#: The sensors' names as Livox writes them.
SHEET_NAMES: dict[str, str] = {"mid40": "Mid-40", "mid70": "Mid-70", "avia": "Avia", "horizon": "Horizon",
                               "tele15": "Tele-15", "hap": "HAP", "mid360": "Mid-360"}
#: What each sheet leaves unpublished and livox-viz chose (also said in the presets' descriptions). Angular
#: noise is 0 because the sheets' angular figure is an accuracy (a bound on a systematic error), not a per-point
#: noise; the return-0 range is the manuals' example.
CHOSEN: dict[str, str] = {
    "all": "angular noise 0, return-0 range 1.5 m, echo separation 0.6 m, threshold 5 x noise",
    "horizon": "blind zone 0.5 m",
    "tele15": "blind zone 1 m, noise 2-4 cm linear over 70-120 m",
    "mid360": "beam divergence 0.1 x 0.1 deg",
}


def describe_sheet(sheet: str) -> str:
    """A short line for a preset's description: which sheet, and what was chosen where it publishes nothing
    (``livox-viz info`` prints the figures)."""
    chosen = ", ".join(([CHOSEN[sheet]] if sheet in CHOSEN else []) + [CHOSEN["all"]])
    return f"Livox {SHEET_NAMES[sheet]} sheet; chosen (unpublished): {chosen}"
