"""The RflySim Livox sensor configuration as a validated, frozen value.

Two RflySim SDKs are in use. The original document's (v2) has the rosette as TypeID 6. Today's (v3, 2024-25)
has the same rosette as TypeID 22 and the Livox Mid-360 as TypeID 23 (TypeID 6 is a sound sensor there), and a
new form of the JSON object: ``EularOrQuat`` (> 0.5: the mount is the quaternion ``SensorAngQuat``, [w, x, y, z]
here, instead of ``SensorAngEular``) and exactly sixteen ``otherParams``. A v3 SDK takes the old form too (the
Mid-360's own example has eight otherParams and no EularOrQuat). So the SDK of a configuration is its TypeID's
(:attr:`SensorConfig.sdk`: what the wire carries), and its form is whether it has ``EularOrQuat``
(:attr:`SensorConfig.v3_form`: what the request and the file look like).

A :class:`SensorConfig` is built from the JSON object of RflySim's vision-sensor
list (``Config.json``). Loading and saving keeps every key the model does not
use (and their order), and the spelling of the mounting-angle key that was read
(``SensorAngEular`` as RflySim writes it, or ``SensorAngEuler`` as the original
document does). Files written from scratch use RflySim's spelling, 8
``otherParams`` and 8 ``SendProtocol`` values, so RflySim's client loads them.

The one option of ours, ``jitter_scope``, travels in an extra key
(``LivoxVizJitterScope``) that RflySim ignores; it is written only when it is
not the default ``"flower"``. So do the Risley track (``LivoxVizRisley``) and the
return model (``LivoxVizReturns``, :mod:`~livox_viz.config.returns_params`)."""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from livox_viz.config.fov import FOV_KEY, FieldOfView
from livox_viz.config.returns_params import (
    DATASHEETS,
    DEFAULT_SHEET,
    RETURN_MODELS,
    RETURN_SLIDERS,
    RETURNS_KEY,
    ReturnParams,
)
from livox_viz.config.risley_params import RisleyParams
from livox_viz.config.shipped import shipped_preset_dir
from livox_viz.config.track_params import TRACK_KEY, TrackParams
from livox_viz.core.atomic import write_text_atomic
from livox_viz.core.errors import ConfigError, quoted
from livox_viz.core.jsonfile import dumps_readable, read_json_file
from livox_viz.core.poses import MAX_ANGLE_RAD, MAX_POSITION_M, pose_from_quaternion
from livox_viz.core.rotations import euler_matrix, quat_from_matrix

JitterScope = Literal["flower", "figure"]


JITTER_SCOPES: tuple[str, ...] = ("flower", "figure")


#: RflySim SDK v2's Livox rosette (the original document's sensor).
LIVOX_TYPE_ID = 6
#: RflySim SDK v3's Livox rosette ("仿Livox mid40激光雷达"): the same otherParams as TypeID 6.
V3_ROSETTE_TYPE_ID = 22
#: RflySim SDK v3's Livox Mid-360: only otherParams[0], the range; scanned here with the ``livox_mid360`` track.
V3_MID360_TYPE_ID = 23
#: The Livox TypeIDs of each SDK.
LIVOX_TYPE_IDS: dict[str, tuple[int, ...]] = {"v2": (LIVOX_TYPE_ID,), "v3": (V3_ROSETTE_TYPE_ID, V3_MID360_TYPE_ID)}
#: The SDKs a configuration can be written for.
SDKS: tuple[str, ...] = ("v2", "v3")
#: What TypeIDs 20 and 21 are in SDK v3 (mechanical lidars), and 6 there (not a lidar), for the refusals.
_OTHER_V3_SENSORS = {20: "a mechanical lidar in the vehicle's frame", 21: "a mechanical lidar in the world frame"}
#: RflySim's Mid-360 frame: DataWidth x DataHeight "have no effect" in its Config.json, its client sizes the
#: block for 64 x 272 points whatever they say.
MID360_FRAME = (64, 272)
#: The shipped preset whose track and field of view a TypeID 23 configuration scans with (unless it has its own).
MID360_PRESET = "livox_mid360"
#: otherParams of the v3 form: exactly sixteen (RflySim's v3 client refuses other lengths).
V3_OTHER_PARAMS = 16


EULER_KEY_RFLYSIM = "SensorAngEular"


EULER_KEY_DOCUMENT = "SensorAngEuler"


#: The v3 form's switch: > 0.5 the mount is :data:`QUATERNION_KEY`, else the Euler angles.
EULAR_OR_QUAT_KEY = "EularOrQuat"


#: The v3 form's mounting quaternion, [w, x, y, z] (scalar first, as RflySim's sensor pages write it).
QUATERNION_KEY = "SensorAngQuat"


JITTER_SCOPE_KEY = "LivoxVizJitterScope"


PATTERN_MODEL_KEY = "LivoxVizPatternModel"


RISLEY_KEY = "LivoxVizRisley"


#: The pattern models: RflySim's petal rosette (scan-model.md), the real sensors' Risley track (risley.md) and
#: the general track of any Livox head (two base frequencies, any orders; :mod:`~livox_viz.config.track_params`).
PATTERN_MODELS: tuple[str, ...] = ("rflysim", "risley", "track")


#: The models whose stream is a deterministic series track (sample k is the series at t = k / rate).
SERIES_MODELS: tuple[str, ...] = ("risley", "track")


DEFAULT_SEND_PROTOCOL: tuple[int, ...] = (0, 127, 0, 0, 1, 9999, 0, 0)


MAX_POINTS_PER_FRAME = 10_000_000


#: Below this length a ``SensorAngQuat`` in use is refused as having no direction (float32 on the wire).
_MIN_QUATERNION_NORM = 1e-6


@dataclass(frozen=True)
class ParamRange:
    """The allowed interval of one numeric field, shared by validation and sliders.

    Parameters
    ----------
    name : str
        The field as a user sees it, e.g. ``"otherParams[1]"``.
    label : str
        What it means, with its unit.
    low, high : float
        The interval's ends.
    low_open, high_open : bool
        Whether an end itself is excluded.
    integer : bool
        Whether the value must be a whole number.
    """

    name: str
    label: str
    low: float
    high: float
    low_open: bool = False
    high_open: bool = False
    integer: bool = False

    def describe(self) -> str:
        """Return the interval in the usual notation, e.g. ``(0, 180)``."""
        left = "(" if self.low_open else "["
        right = ")" if self.high_open else "]"
        kind = "an integer in " if self.integer else ""
        return f"{kind}{left}{_fmt(self.low)}, {_fmt(self.high)}{right}"

    def contains(self, value: float) -> bool:
        """Whether ``value`` is finite and inside the interval."""
        if not math.isfinite(value):
            return False
        if self.integer and value != int(value):
            return False
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def check(self, value: Any) -> float:
        """Return ``value`` as a float, or raise :class:`ConfigError` naming the range."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(
                f"{self.name} ({self.label}) must be a number, got {quoted(value)}; "
                f"allowed: {self.describe()}"
            )
        if not self.contains(float(value)):
            raise ConfigError(
                f"{self.name} ({self.label}) = {quoted(value)} is out of range; "
                f"allowed: {self.describe()}"
            )
        return float(value)


def _fmt(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


#: The validated range of every tunable field, keyed by the attribute name.
PARAM_RANGES: dict[str, ParamRange] = {
    "data_width": ParamRange("DataWidth", "points per arc", 1, 5000, integer=True),
    "data_height": ParamRange("DataHeight", "arcs per frame", 1, 2000, integer=True),
    "data_check_freq": ParamRange("DataCheckFreq", "frames per second", 1, 1000, integer=True),
    "camera_fov": ParamRange("CameraFOV", "full field of view, deg", 0, 180, True, True),
    "range_max": ParamRange("otherParams[0]", "max range, m", 0, 10000, low_open=True),
    "petal_height": ParamRange("otherParams[1]", "petal height h, deg", 0, 45, low_open=True),
    "spacing_exponent": ParamRange("otherParams[2]", "spacing exponent p", 0, 10, low_open=True),
    "tip_exponent": ParamRange("otherParams[3]", "tip exponent q", 0, 10, low_open=True),
    "figure8_per_flower": ParamRange("otherParams[4]", "figure-8s per flower N8", 1, 360, integer=True),
    "flowers_per_figure": ParamRange("otherParams[5]", "flowers per figure Nf", 1, 360, integer=True),
    "jitter_max_deg": ParamRange("otherParams[6]", "random rotation, deg", 0, 360),
    "prism_rpm_a": ParamRange("LivoxVizRisley prism A", "prism A speed, rpm", -20000, 20000),
    "prism_rpm_b": ParamRange("LivoxVizRisley prism B", "prism B speed, rpm", -20000, 20000),
    "deflection_a": ParamRange("LivoxVizRisley deflection A", "prism A deflection, deg", 0, 45, low_open=True),
    "deflection_b": ParamRange("LivoxVizRisley deflection B", "prism B deflection, deg", 0, 45, low_open=True),
    "laser_spacing": ParamRange("LivoxVizRisley laser_spacing", "lasers' spacing, x fitted", 0, 10),
    "base_rpm_a": ParamRange("LivoxVizTrack base A", "base A speed, rpm", -300000, 300000),
    "base_rpm_b": ParamRange("LivoxVizTrack base B", "base B speed, rpm", -300000, 300000),
    **{f"returns_{name}": ParamRange(f"{RETURNS_KEY} {name}", label, low, high, low_open=low > 0)
       for name, (label, low, high) in RETURN_SLIDERS.items()},
}


#: The tunable fields of the Risley model (they need ``LivoxVizRisley`` parameters).
RISLEY_PARAMS: tuple[str, ...] = ("prism_rpm_a", "prism_rpm_b", "deflection_a", "deflection_b", "laser_spacing")
#: The tunable fields of the return model (``LivoxVizReturns``; the Mid-70's sheet where a configuration has none).
RETURNS_PARAMS: tuple[str, ...] = tuple(f"returns_{name}" for name in RETURN_SLIDERS)


#: The tunable fields of the track model (they need ``LivoxVizTrack`` parameters): its two base speeds.
TRACK_PARAMS: tuple[str, ...] = ("base_rpm_a", "base_rpm_b")


_INTEGER_KEYS = {
    "SeqID": "SeqID",
    "TypeID": "TypeID",
    "TargetCopter": "TargetCopter",
    "TargetMountType": "TargetMountType",
    "DataWidth": "data_width",
    "DataHeight": "data_height",
    "DataCheckFreq": "data_check_freq",
}


_REQUIRED_KEYS = (
    "SeqID",
    "TypeID",
    "TargetCopter",
    "TargetMountType",
    "DataWidth",
    "DataHeight",
    "DataCheckFreq",
    "SendProtocol",
    "CameraFOV",
    "SensorPosXYZ",
    "otherParams",
)


_OTHER_PARAM_FIELDS = (
    "range_max",
    "petal_height",
    "spacing_exponent",
    "tip_exponent",
    "figure8_per_flower",
    "flowers_per_figure",
    "jitter_max_deg",
)


@dataclass(frozen=True)
class SensorConfig:
    """One Livox sensor of RflySim (TypeID 6 in SDK v2; 22 or 23 in SDK v3), validated on construction.

    Parameters
    ----------
    data_width : int
        W, points on one arc (half a petal).
    data_height : int
        H, arcs per published frame.
    data_check_freq : int
        F, frames per second.
    camera_fov : float
        Full field of view, degrees (twice the petal length).
    other_params : tuple of float
        ``otherParams`` as 8 values (16 in the v3 form, the last eight kept as read): range (m), petal
        height h (deg), spacing exponent p, tip exponent q, figure-8s per flower N8, flowers per figure
        Nf, maximum jitter (deg), and an unused eighth value. A Mid-360 (TypeID 23) uses only the range.
    sensor_pos_xyz : tuple of float
        Sensor origin in the vehicle body frame (FRD), metres.
    sensor_ang_euler : tuple of float
        Mounting angles [roll, pitch, yaw] relative to the body, radians.
    eular_or_quat : float, optional
        The v3 form's ``EularOrQuat`` (None: the old form, without it): above 0.5 the mount is
        :attr:`sensor_ang_quat`, else :attr:`sensor_ang_euler`.
    sensor_ang_quat : tuple of float, optional
        The v3 form's ``SensorAngQuat``, [w, x, y, z] as written (normalised where it is used; one of
        zero length is refused where it is used).
    seq_id, type_id, target_copter, target_mount_type : int
        RflySim's bookkeeping fields, preserved.
    send_protocol : tuple of int
        RflySim's ``SendProtocol``: [0] 1 = UDP / 0 = shared memory,
        [1..4] IPv4 bytes, [5] port, [6..7] unused.
    jitter_scope : {"flower", "figure"}
        When the random rotation is added to the running offset.
    pattern_model : {"rflysim", "risley", "track"}
        Which pattern the sensor scans: RflySim's rosette from ``otherParams``,
        the Risley-prism track of :attr:`risley` or the general track of :attr:`track`.
    risley : RisleyParams, optional
        The Risley track (``LivoxVizRisley``); needed when ``pattern_model`` is ``"risley"``.
    track : TrackParams, optional
        The general track (``LivoxVizTrack``); needed when ``pattern_model`` is ``"track"``.
    fov : FieldOfView, optional
        The real sensor's field of view (``LivoxVizFieldOfView``) for its track; default (and always for
        the rosette) the cone of half-angle CameraFOV / 2. See :attr:`field_of_view`.
    returns : ReturnParams, optional
        The sensor's return model (``LivoxVizReturns``); None is the ideal model.
    source : dict
        The JSON object as it was read (key order and unknown keys are kept
        for saving); empty for a configuration made from scratch.
    euler_key : str
        The spelling of the mounting-angle key to write.
    """

    data_width: int = 250
    data_height: int = 40
    data_check_freq: int = 10
    camera_fov: float = 70.432
    other_params: tuple[float, ...] = (600.0, 2.956, 1.4, 1.18, 10.0, 5.0, 1.0, 0.0)
    sensor_pos_xyz: tuple[float, float, float] = (0.0, 0.0, -0.3)
    sensor_ang_euler: tuple[float, float, float] = (0.0, 0.0, 0.0)
    eular_or_quat: float | None = None
    sensor_ang_quat: tuple[float, ...] | None = None
    seq_id: int = 0
    type_id: int = LIVOX_TYPE_ID
    target_copter: int = 1
    target_mount_type: int = 0
    send_protocol: tuple[int, ...] = DEFAULT_SEND_PROTOCOL
    jitter_scope: str = "flower"
    pattern_model: str = "rflysim"
    risley: RisleyParams | None = None
    track: TrackParams | None = None
    fov: FieldOfView | None = None
    returns: ReturnParams | None = None
    source: Mapping[str, Any] = field(default_factory=dict, compare=False, repr=False)
    euler_key: str = field(default=EULER_KEY_RFLYSIM, compare=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("data_width", "data_height", "data_check_freq"):
            _check_int(PARAM_RANGES[name], getattr(self, name))
        self._check_type_and_form()
        if self.type_id == V3_MID360_TYPE_ID:
            # RflySim's Mid-360 has its own frame and pattern: W x H and the rosette's fields say nothing.
            object.__setattr__(self, "data_width", MID360_FRAME[0])
            object.__setattr__(self, "data_height", MID360_FRAME[1])
            _check_finite("CameraFOV", self.camera_fov)
        else:
            PARAM_RANGES["camera_fov"].check(self.camera_fov)
        params = tuple(self.other_params)
        if self.v3_form and len(params) != V3_OTHER_PARAMS:
            raise ConfigError(
                f"otherParams has {len(params)} values; allowed: exactly {V3_OTHER_PARAMS} in a configuration "
                f"with {EULAR_OR_QUAT_KEY} (RflySim v3), or 8 without it"
            )
        if not self.v3_form and not 7 <= len(params) <= 8:
            raise ConfigError(
                f"otherParams has {len(params)} values; allowed: 7 or 8 "
                "(range, petal height, p, q, figure-8s per flower, flowers per figure, jitter[, unused]), "
                f"or {V3_OTHER_PARAMS} with {EULAR_OR_QUAT_KEY} and {QUATERNION_KEY} (RflySim v3)"
            )
        if self.type_id == V3_MID360_TYPE_ID:
            PARAM_RANGES["range_max"].check(params[0])
            first_free = 1
        else:
            for name, value in zip(_OTHER_PARAM_FIELDS, params[:7], strict=True):
                PARAM_RANGES[name].check(value)
            first_free = 7
        for index in range(first_free, len(params)):
            _check_finite(f"otherParams[{index}]", params[index])
        if self.data_width * self.data_height > MAX_POINTS_PER_FRAME:
            raise ConfigError(
                f"DataWidth*DataHeight = {self.data_width * self.data_height} points per frame; "
                f"allowed: at most {MAX_POINTS_PER_FRAME}"
            )
        _check_vector("SensorPosXYZ", self.sensor_pos_xyz, 3)
        if not all(abs(v) <= MAX_POSITION_M for v in self.sensor_pos_xyz):  # 1e308 overflowed the float32 ray casts
            raise ConfigError(f"SensorPosXYZ = {quoted(list(self.sensor_pos_xyz))}; allowed: the mount's offset "
                              f"from the vehicle, each within {MAX_POSITION_M:g} m")
        _check_vector(self.euler_key, self.sensor_ang_euler, 3)
        if not all(abs(v) <= MAX_ANGLE_RAD for v in self.sensor_ang_euler):
            raise ConfigError(f"{self.euler_key} = {quoted(list(self.sensor_ang_euler))}; allowed: roll, pitch, yaw, "
                              f"each within {MAX_ANGLE_RAD:g} rad")
        if len(self.send_protocol) != 8 or not all(_is_int(v) for v in self.send_protocol):
            raise ConfigError(
                f"SendProtocol = {quoted(list(self.send_protocol))}; allowed: a list of 8 integers"
            )
        if self.jitter_scope not in JITTER_SCOPES:
            raise ConfigError(
                f"{JITTER_SCOPE_KEY} = {quoted(self.jitter_scope)}; allowed: {' or '.join(JITTER_SCOPES)}"
            )
        if self.type_id == V3_MID360_TYPE_ID:
            # The Mid-360 scans its track (the shipped livox_mid360's, unless the configuration carries its own).
            track, fov = mid360_track()
            object.__setattr__(self, "pattern_model", "track")
            object.__setattr__(self, "track", self.track or track)
            object.__setattr__(self, "fov", self.fov or fov)
        if self.pattern_model not in PATTERN_MODELS:
            raise ConfigError(
                f"{PATTERN_MODEL_KEY} = {quoted(self.pattern_model)}; allowed: {' or '.join(PATTERN_MODELS)}"
            )
        if self.pattern_model == "risley" and self.risley is None:
            raise ConfigError(f"{PATTERN_MODEL_KEY} is 'risley' but there is no {RISLEY_KEY} object")
        if self.pattern_model == "track" and self.track is None:
            raise ConfigError(f"{PATTERN_MODEL_KEY} is 'track' but there is no {TRACK_KEY} object")
        if self.track is not None and self.track.form == "spin" and (self.fov is None or self.fov.plane != "panorama"):
            raise ConfigError(f"a spin track ({TRACK_KEY}.form 'spin') turns all the way round; it needs a "
                              f'{FOV_KEY} band (e.g. {{"shape": "band", "elevation_deg": [-7, 52]}})')
        if self.returns is not None and self.returns.model == "datasheet" and (
                self.returns.blind_zone_m >= self.other_params[0]):
            raise ConfigError(f"{RETURNS_KEY}.blind_zone_m = {self.returns.blind_zone_m:g} m reaches the range "
                              f"otherParams[0] = {self.other_params[0]:g} m: a datasheet scan would return nothing; "
                              "allowed: a blind zone nearer than the range")
        if self.euler_key not in (EULER_KEY_RFLYSIM, EULER_KEY_DOCUMENT):
            raise ConfigError(
                f"euler_key = {quoted(self.euler_key)}; allowed: {EULER_KEY_RFLYSIM} or {EULER_KEY_DOCUMENT}"
            )
        for name, key in (("seq_id", "SeqID"), ("target_copter", "TargetCopter"),
                          ("target_mount_type", "TargetMountType")):
            value = getattr(self, name)
            # RflySim's request carries them as uint16: -1 or 10**30 was described by info, and failed only when
            # sent (or named a shared memory block RflySim3DImg_-1).
            if not _is_int(value) or not 0 <= value <= 0xFFFF:
                raise ConfigError(f"{key} = {quoted(value)}; allowed: an integer from 0 to 65535 (RflySim sends "
                                  "it as a uint16)")
        # Normalise sequences to tuples of floats so equal configs compare equal.
        padded = max(len(params), 8)
        object.__setattr__(self, "other_params", tuple(float(v) for v in params) + (0.0,) * (padded - len(params)))
        object.__setattr__(self, "sensor_pos_xyz", tuple(float(v) for v in self.sensor_pos_xyz))
        object.__setattr__(self, "sensor_ang_euler", tuple(float(v) for v in self.sensor_ang_euler))
        object.__setattr__(self, "send_protocol", tuple(int(v) for v in self.send_protocol))
        if self.eular_or_quat is not None:
            object.__setattr__(self, "eular_or_quat", float(self.eular_or_quat))
        if self.sensor_ang_quat is not None:
            object.__setattr__(self, "sensor_ang_quat", tuple(float(v) for v in self.sensor_ang_quat))

    def _check_type_and_form(self) -> None:
        """TypeID against the SDKs' Livox sensors, and the v3 form's fields (``EularOrQuat``, ``SensorAngQuat``)."""
        named = (f"the Livox TypeIDs are {LIVOX_TYPE_ID} in RflySim SDK v2 (the rosette) and "
                 f"{V3_ROSETTE_TYPE_ID} (the rosette) or {V3_MID360_TYPE_ID} (the Mid-360) in SDK v3")
        if not _is_int(self.type_id) or self.type_id not in (*LIVOX_TYPE_IDS["v2"], *LIVOX_TYPE_IDS["v3"]):
            what = _OTHER_V3_SENSORS.get(self.type_id)
            kind = f" ({what} of RflySim SDK v3)" if what else ""
            raise ConfigError(f"TypeID = {quoted(self.type_id)}{kind} is not a Livox lidar; allowed: {named}")
        if self.eular_or_quat is None:
            if self.sensor_ang_quat is not None:
                raise ConfigError(f"{QUATERNION_KEY} without {EULAR_OR_QUAT_KEY}; allowed: both (RflySim v3: "
                                  f"{EULAR_OR_QUAT_KEY} > 0.5 takes the quaternion) or neither")
            return
        if self.type_id == LIVOX_TYPE_ID:
            raise ConfigError(f"TypeID = 6 with {EULAR_OR_QUAT_KEY} (an RflySim v3 configuration) is the sound sensor "
                              f"of SDK v3, not a Livox lidar; allowed: {named}")
        if isinstance(self.eular_or_quat, bool) or not isinstance(self.eular_or_quat, (int, float)) \
                or not math.isfinite(self.eular_or_quat) or abs(self.eular_or_quat) > FLOAT32_MAX:
            raise ConfigError(f"{EULAR_OR_QUAT_KEY} = {quoted(self.eular_or_quat)}; allowed: a number (> 0.5: the "
                              f"mount is {QUATERNION_KEY}, else {self.euler_key}) within the 32-bit float RflySim "
                              f"reads it as, +-{FLOAT32_MAX:.4g}")
        if self.sensor_ang_quat is None:
            raise ConfigError(f"missing key {QUATERNION_KEY!r}; a configuration with {EULAR_OR_QUAT_KEY} (RflySim "
                              "v3) needs it: the mounting quaternion [w, x, y, z]")
        _check_vector(QUATERNION_KEY, self.sensor_ang_quat, 4)
        _check_float32(QUATERNION_KEY, self.sensor_ang_quat)
        if self.eular_or_quat > 0.5 and math.hypot(*self.sensor_ang_quat) < _MIN_QUATERNION_NORM:
            raise ConfigError(f"{QUATERNION_KEY} = {quoted(list(self.sensor_ang_quat))} has zero length, and "
                              f"{EULAR_OR_QUAT_KEY} > 0.5 mounts the sensor with it; allowed: a rotation "
                              "quaternion [w, x, y, z] of non-zero length (normalised here)")

    # The SDK and the form --------------------------------------------------------------
    @property
    def sdk(self) -> str:
        """``"v2"`` or ``"v3"``: the RflySim SDK whose sensor the TypeID is (6; 22 or 23), so what the wire carries
        (three int16 a point and the ``<4i1d`` header; four int16 and the ``<6i1d`` header)."""
        return "v3" if self.type_id in LIVOX_TYPE_IDS["v3"] else "v2"

    @property
    def v3_form(self) -> bool:
        """Whether the configuration has the v3 form (``EularOrQuat``, ``SensorAngQuat``, 16 otherParams): what
        RflySim's v3 client sends the 144-byte ``<16H28f`` request for (the 92-byte ``<16H15f`` without it)."""
        return self.eular_or_quat is not None

    @property
    def mount_quaternion(self) -> tuple[float, float, float, float] | None:
        """The mount's unit quaternion [x, y, z, w] (sensor FRD -> body FRD) when ``EularOrQuat`` > 0.5 chooses
        ``SensorAngQuat``; None when the Euler angles are the mount."""
        if self.eular_or_quat is None or self.eular_or_quat <= 0.5 or self.sensor_ang_quat is None:
            return None
        w, x, y, z = self.sensor_ang_quat
        norm = math.sqrt(w * w + x * x + y * y + z * z)
        return (x / norm, y / norm, z / norm, w / norm)

    def with_sdk(self, sdk: str) -> SensorConfig:
        """The same sensor written for RflySim SDK ``sdk`` ("v2" or "v3").

        v3: TypeID 22 (23 for a track that sees all around, the Mid-360's), the v3 form: ``EularOrQuat`` 0 (the
        Euler angles stay the mount), ``SensorAngQuat`` the same rotation [w, x, y, z], otherParams padded to 16
        with zeros; the new keys go where RflySim's own files have them. A configuration already in the v3
        form is kept as it is. v2: TypeID 6, the old form: a quaternion mount becomes Euler angles, the v3 keys
        go, otherParams keep their first eight.

        Raises
        ------
        ConfigError
            For a Mid-360 (TypeID 23) or otherParams[8..15] not all zero asked for v2 (SDK v2 has neither), or
            an SDK not in :data:`SDKS`.
        """
        if sdk not in SDKS:
            raise ConfigError(f"SDK {quoted(sdk)}; allowed: {' or '.join(SDKS)}")
        if sdk == "v3":
            if self.sdk == "v3" and self.v3_form:
                return self
            mid360 = self.type_id == V3_MID360_TYPE_ID or (self.pattern_model == "track"
                                                           and self.pattern_plane == "panorama")
            quaternion = _quaternion_wxyz(*self.sensor_ang_euler)
            source = _insert_after(dict(self.source), self.euler_key, {QUATERNION_KEY: None})
            source = _insert_after(source, "SensorPosXYZ", {EULAR_OR_QUAT_KEY: None})
            return replace(self, type_id=V3_MID360_TYPE_ID if mid360 else V3_ROSETTE_TYPE_ID, eular_or_quat=0.0,
                           sensor_ang_quat=quaternion, source=source,
                           other_params=self.other_params + (0.0,) * (V3_OTHER_PARAMS - len(self.other_params)))
        if self.type_id == V3_MID360_TYPE_ID:
            raise ConfigError(f"RflySim SDK v2 has no Mid-360 (TypeID {V3_MID360_TYPE_ID}); allowed: --sdk v3 for it")
        extra = self.other_params[8:]
        if any(extra):
            raise ConfigError(f"otherParams[8..15] = {[_json_number(v) for v in extra]}: SDK v2 has room for 8 "
                              "otherParams only; allowed: --sdk v3, or those values all 0")
        euler = self.sensor_ang_euler
        if self.mount_quaternion is not None:
            euler = _euler_of_quaternion(*self.mount_quaternion)
        return replace(self, type_id=LIVOX_TYPE_ID, eular_or_quat=None, sensor_ang_quat=None,
                       sensor_ang_euler=euler, other_params=self.other_params[:8])

    # Derived figures of the model -------------------------------------------------
    @property
    def range_max(self) -> float:
        """Maximum range and int16 scale, metres (``otherParams[0]``)."""
        return self.other_params[0]

    @property
    def petal_height(self) -> float:
        """Petal height h, degrees (``otherParams[1]``): how far each arc rises from the petal's axis at its middle,
        half the petal's width."""
        return self.other_params[1]

    @property
    def spacing_exponent(self) -> float:
        """Point-spacing exponent p along an arc (``otherParams[2]``)."""
        return self.other_params[2]

    @property
    def tip_exponent(self) -> float:
        """Calibration exponent q of the tip-side part of an arc (``otherParams[3]``)."""
        return self.other_params[3]

    @property
    def figure8_per_flower(self) -> int:
        """N8, figure-8s per flower (``otherParams[4]``)."""
        return int(self.other_params[4])

    @property
    def flowers_per_figure(self) -> int:
        """Nf, flowers per figure (``otherParams[5]``)."""
        return int(self.other_params[5])

    @property
    def jitter_max_deg(self) -> float:
        """Largest random rotation added to the running offset, degrees (``otherParams[6]``)."""
        return self.other_params[6]

    @property
    def lasers(self) -> int:
        """K, lasers firing in turn in the pattern in use (1 for the rosette)."""
        return self.series.lasers if self.pattern_model in SERIES_MODELS else 1

    @property
    def series(self) -> RisleyParams | TrackParams:
        """The series the stream evaluates: :attr:`risley` or :attr:`track`, by the pattern model."""
        params = self.track if self.pattern_model == "track" else self.risley
        if params is None:
            raise ConfigError(f"the {self.pattern_model} model has no series parameters")
        return params

    @property
    def field_of_view(self) -> FieldOfView:
        """Where the pattern in use looks: the track's own field of view, or the cone of CameraFOV / 2.

        The rosette always scans the cone (RflySim's model); a Risley or track configuration without a
        ``LivoxVizFieldOfView`` does too.
        """
        if self.pattern_model in SERIES_MODELS and self.fov is not None:
            return self.fov
        return _cone(self.camera_fov)

    @property
    def pattern_plane(self) -> str:
        """``"boresight"`` or ``"panorama"``: the plane of the pattern's angles (:mod:`~livox_viz.config.fov`)."""
        return self.field_of_view.plane

    @property
    def points_per_frame(self) -> int:
        """W*H, points in one published frame."""
        return self.data_width * self.data_height

    @property
    def point_rate(self) -> int:
        """W*H*F, points per second."""
        return self.points_per_frame * self.data_check_freq

    @property
    def points_per_figure8(self) -> int:
        """4W: a figure-8 is four arcs."""
        return 4 * self.data_width

    @property
    def points_per_flower(self) -> int:
        """4W*N8."""
        return self.points_per_figure8 * self.figure8_per_flower

    @property
    def points_per_figure(self) -> int:
        """4W*N8*Nf."""
        return self.points_per_flower * self.flowers_per_figure

    @property
    def unit_points(self) -> dict[str, int]:
        """Points in each unit of the stream, smallest first: arc, petal, figure8, flower, figure, frame.

        The Risley track has no petal structure: its only unit is the frame.
        """
        if self.pattern_model in SERIES_MODELS:
            return {"frame": self.points_per_frame}
        return {
            "arc": self.data_width,
            "petal": 2 * self.data_width,
            "figure8": self.points_per_figure8,
            "flower": self.points_per_flower,
            "figure": self.points_per_figure,
            "frame": self.points_per_frame,
        }

    @property
    def petal_spacing_deg(self) -> float:
        """Angle between neighbouring petals of one flower, 180/N8 degrees."""
        return 180.0 / self.figure8_per_flower

    @property
    def flower_step_deg(self) -> float:
        """Rotation from one flower of a figure to the next, (180/N8)/Nf degrees."""
        return self.petal_spacing_deg / self.flowers_per_figure

    @property
    def half_fov_deg(self) -> float:
        """Half-angle of the FOV cone (the petal length), degrees."""
        return self.camera_fov / 2.0

    @property
    def range_step(self) -> float:
        """The int16 quantisation step range/32767, metres."""
        return self.range_max / 32767.0

    def with_param(self, name: str, value: float) -> SensorConfig:
        """Return a copy with one tunable field (a key of :data:`PARAM_RANGES`) changed.

        Raises :class:`ConfigError` if the value is outside the field's range.
        """
        if name not in PARAM_RANGES:
            raise ConfigError(f"unknown parameter {quoted(name)}; allowed: {', '.join(PARAM_RANGES)}")
        spec = PARAM_RANGES[name]
        value = spec.check(value)
        if spec.integer:
            value = int(value)
        if name in RISLEY_PARAMS:
            return replace(self, risley=_risley_with(self._require_risley(), name, value))
        if name in TRACK_PARAMS:
            track = self._require_track()
            hz = list(track.base_hz)
            hz[name.endswith("_b")] = value / 60.0
            return replace(self, track=replace(track, base_hz=tuple(hz)))
        if name in RETURNS_PARAMS:
            return replace(self, returns=self.return_params.with_slider(name.removeprefix("returns_"), value))
        if name in _OTHER_PARAM_FIELDS:
            params = list(self.other_params)
            params[_OTHER_PARAM_FIELDS.index(name)] = value
            return replace(self, other_params=tuple(params))
        return replace(self, **{name: value})

    def param_value(self, name: str) -> float:
        """The current value of a tunable field named as in :data:`PARAM_RANGES`."""
        if name in RISLEY_PARAMS:
            risley = self._require_risley()
            return {"prism_rpm_a": risley.prism_rpm[0], "prism_rpm_b": risley.prism_rpm[1],
                    "deflection_a": risley.deflection_deg[0], "deflection_b": risley.deflection_deg[1],
                    "laser_spacing": risley.laser_spacing}[name]
        if name in TRACK_PARAMS:
            return self._require_track().base_rpm[name.endswith("_b")]
        if name in RETURNS_PARAMS:
            return self.return_params.slider_value(name.removeprefix("returns_"))
        return float(getattr(self, name))

    def _require_track(self) -> TrackParams:
        if self.track is None:
            raise ConfigError(f"this configuration has no {TRACK_KEY} parameters; load a track preset "
                              "(e.g. livox_horizon)")
        return self.track

    def _require_risley(self) -> RisleyParams:
        if self.risley is None:
            raise ConfigError(f"this configuration has no {RISLEY_KEY} parameters; load a Risley preset "
                              "(e.g. livox_mid70_risley)")
        return self.risley

    def with_pattern_model(self, model: str) -> SensorConfig:
        """A copy that scans with ``model`` (a name of :data:`PATTERN_MODELS`)."""
        return replace(self, pattern_model=model)

    @property
    def return_params(self) -> ReturnParams:
        """The return model in effect: ``LivoxVizReturns``, or the Mid-70's sheet in the ideal model."""
        if self.returns is not None:
            return self.returns
        return replace(DATASHEETS[DEFAULT_SHEET], model="ideal")

    @property
    def returns_model(self) -> str:
        """The return model scans use: "ideal" (the exact first hit, as RflySim computes) or "datasheet"."""
        return self.return_params.model

    def with_returns_model(self, model: str) -> SensorConfig:
        """A copy whose scans use the ``model`` ("ideal" or "datasheet") return model.

        A configuration without a return model gets the Mid-70's datasheet.
        """
        if model not in RETURN_MODELS:
            raise ConfigError(f"return model {quoted(model)}; allowed: {' or '.join(RETURN_MODELS)}")
        return replace(self, returns=replace(self.return_params, model=model))

    # JSON ---------------------------------------------------------------------------
    def to_json_dict(self) -> dict[str, Any]:
        """The RflySim JSON object, in the key order that was read (new keys last)."""
        values: dict[str, Any] = {
            "SeqID": self.seq_id,
            "TypeID": self.type_id,
            "TargetCopter": self.target_copter,
            "TargetMountType": self.target_mount_type,
            "DataWidth": self.data_width,
            "DataHeight": self.data_height,
            "DataCheckFreq": self.data_check_freq,
            "SendProtocol": list(self.send_protocol),
            "CameraFOV": _json_number(self.camera_fov),
            "SensorPosXYZ": [_json_number(v) for v in self.sensor_pos_xyz],
            **({EULAR_OR_QUAT_KEY: _json_number(self.eular_or_quat)} if self.eular_or_quat is not None else {}),
            self.euler_key: [_json_number(v) for v in self.sensor_ang_euler],
            **({QUATERNION_KEY: [_json_number(v) for v in self.sensor_ang_quat]}
               if self.sensor_ang_quat is not None else {}),
            "otherParams": [_json_number(v) for v in self.other_params],
        }
        if self.type_id == V3_MID360_TYPE_ID:
            # Its W x H have no effect in RflySim (the frame is 64 x 272): written back as they were read.
            for key in ("DataWidth", "DataHeight"):
                if key in self.source:
                    values[key] = self.source[key]
        out: dict[str, Any] = {}
        for key, old in self.source.items():
            if key in (EULAR_OR_QUAT_KEY, QUATERNION_KEY) and key not in values:
                continue  # written as the old form (see with_sdk)
            out[key] = values.pop(key) if key in values else old
        out.update(values)
        if self.jitter_scope != "flower" or JITTER_SCOPE_KEY in out:
            out[JITTER_SCOPE_KEY] = self.jitter_scope
        implied = self._implied_by_type()
        if (self.pattern_model != "rflysim" and PATTERN_MODEL_KEY not in implied) or PATTERN_MODEL_KEY in out:
            out[PATTERN_MODEL_KEY] = self.pattern_model
        for key, params in ((RISLEY_KEY, self.risley), (TRACK_KEY, self.track), (FOV_KEY, self.fov)):
            if params is not None and (key not in implied or key in out):
                out[key] = params.to_json()
            elif params is None:
                out.pop(key, None)
        if self.returns is not None:
            out[RETURNS_KEY] = self.returns.to_json()
        else:
            out.pop(RETURNS_KEY, None)
        return out

    def _implied_by_type(self) -> set[str]:
        """Our keys a TypeID 23 configuration need not carry: the Mid-360's pattern model, and its track and field
        of view while they are the shipped ones (a RflySim file stays as RflySim wrote it)."""
        if self.type_id != V3_MID360_TYPE_ID:
            return set()
        track, fov = mid360_track()
        return {PATTERN_MODEL_KEY, *([TRACK_KEY] if self.track == track else []),
                *([FOV_KEY] if self.fov == fov else [])}

    @classmethod
    def from_json_dict(cls, data: Any) -> SensorConfig:
        """Build and validate a configuration from one RflySim sensor object.

        Raises
        ------
        ConfigError
            Naming the missing or bad key and what is allowed.
        """
        if not isinstance(data, Mapping):
            raise ConfigError(
                f"a sensor configuration must be a JSON object, got {type(data).__name__}"
            )
        for key in _REQUIRED_KEYS:
            if key not in data:
                raise ConfigError(f"missing key {quoted(key)}; a RflySim sensor object needs "
                                  f"{', '.join(_REQUIRED_KEYS)}")
        if EULER_KEY_RFLYSIM in data:
            euler_key = EULER_KEY_RFLYSIM
        elif EULER_KEY_DOCUMENT in data:
            euler_key = EULER_KEY_DOCUMENT
        else:
            raise ConfigError(
                f"missing key {quoted(EULER_KEY_RFLYSIM)} (or {quoted(EULER_KEY_DOCUMENT)}): "
                "the sensor mounting angles [roll, pitch, yaw] in radians"
            )
        ints: dict[str, int] = {}
        for key in _INTEGER_KEYS:
            value = data[key]
            if not _is_int(value):
                spec = PARAM_RANGES.get(_INTEGER_KEYS[key])
                allowed = spec.describe() if spec is not None else "an integer"
                raise ConfigError(f"{key} = {quoted(value)}; allowed: {allowed}")
            ints[key] = int(value)
        v3_form = EULAR_OR_QUAT_KEY in data
        switch = data.get(EULAR_OR_QUAT_KEY)
        if v3_form and (isinstance(switch, bool) or not isinstance(switch, (int, float))):
            # null among them: None is how a configuration says it has no EularOrQuat (the old form).
            raise ConfigError(f"{EULAR_OR_QUAT_KEY} = {quoted(switch)}; allowed: a number (> 0.5: the mount is "
                              f"{QUATERNION_KEY}, else {euler_key})")
        listed = ("SendProtocol", "otherParams", "SensorPosXYZ", euler_key, *((QUATERNION_KEY,) if v3_form else ()))
        if v3_form and QUATERNION_KEY not in data:
            raise ConfigError(f"missing key {QUATERNION_KEY!r}; a configuration with {EULAR_OR_QUAT_KEY} (RflySim v3) "
                              "needs it: the mounting quaternion [w, x, y, z]")
        for key in listed:
            if not isinstance(data[key], list):
                raise ConfigError(f"{key} = {quoted(data[key])}; allowed: a JSON list of numbers")
        other_params = data["otherParams"]
        for index, value in enumerate(other_params):
            _check_finite(f"otherParams[{index}]", value)
        camera_fov = data["CameraFOV"]
        _check_finite("CameraFOV", camera_fov)
        scope = data.get(JITTER_SCOPE_KEY, "flower")
        risley = RisleyParams.from_json(data[RISLEY_KEY]) if RISLEY_KEY in data else None
        track = TrackParams.from_json(data[TRACK_KEY]) if TRACK_KEY in data else None
        fov = FieldOfView.from_json(data[FOV_KEY]) if FOV_KEY in data else None
        returns = ReturnParams.from_json(data[RETURNS_KEY]) if RETURNS_KEY in data else None
        return cls(
            data_width=ints["DataWidth"],
            data_height=ints["DataHeight"],
            data_check_freq=ints["DataCheckFreq"],
            camera_fov=float(camera_fov),
            other_params=tuple(other_params),
            sensor_pos_xyz=tuple(data["SensorPosXYZ"]),
            sensor_ang_euler=tuple(data[euler_key]),
            eular_or_quat=data[EULAR_OR_QUAT_KEY] if v3_form else None,
            sensor_ang_quat=tuple(data[QUATERNION_KEY]) if v3_form else None,
            seq_id=ints["SeqID"],
            type_id=ints["TypeID"],
            target_copter=ints["TargetCopter"],
            target_mount_type=ints["TargetMountType"],
            send_protocol=tuple(data["SendProtocol"]),
            jitter_scope=scope,
            pattern_model=data.get(PATTERN_MODEL_KEY, "rflysim"),
            risley=risley,
            track=track,
            fov=fov,
            returns=returns,
            source=dict(data),
            euler_key=euler_key,
        )


def _insert_after(data: dict[str, Any], key: str, new: dict[str, Any]) -> dict[str, Any]:
    """``data`` with the keys of ``new`` right after ``key`` (at the end when ``key`` is not there)."""
    if key not in data:
        return {**data, **new}
    out: dict[str, Any] = {}
    for name, value in data.items():
        out[name] = value
        if name == key:
            out.update(new)
    return out


def _quaternion_wxyz(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    """The rotation of Z-Y-X Euler angles (radians) as a unit quaternion [w, x, y, z] (RflySim's order)."""
    x, y, z, w = (float(v) for v in quat_from_matrix(euler_matrix(roll, pitch, yaw)))
    return (w, x, y, z)


def _euler_of_quaternion(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """Z-Y-X Euler angles [roll, pitch, yaw] (radians) of a unit quaternion [x, y, z, w]."""
    pose = pose_from_quaternion(np.zeros(3), np.array([x, y, z, w]))
    return (pose.roll, pose.pitch, pose.yaw)


def _risley_with(risley: RisleyParams, name: str, value: float) -> RisleyParams:
    """The Risley parameters with one slider's value (rpm, degrees or the spacing scale) changed."""
    if name in ("prism_rpm_a", "prism_rpm_b"):
        hz = list(risley.prism_hz)
        hz[name.endswith("_b")] = value / 60.0
        return replace(risley, prism_hz=tuple(hz))
    if name in ("deflection_a", "deflection_b"):
        deflection = list(risley.deflection_deg)
        deflection[name.endswith("_b")] = value
        return replace(risley, deflection_deg=tuple(deflection))
    return replace(risley, laser_spacing=value)


def frame_layout(rate: float, lasers: int = 1, width: int | None = None) -> tuple[int, int, int]:
    """DataWidth, DataHeight and DataCheckFreq whose product is ``rate`` points per second, about 10 frames/s.

    The frame rate F is the divisor of the rate nearest 10 frames per second
    (1 to 1000) whose frame holds a whole number of firing groups of
    ``lasers`` (so every frame starts with laser 0) where one does; the frame
    is then split into W x H with W nearest ``width`` (default: 40 rows,
    H = 40, as the shipped presets have).

    Parameters
    ----------
    rate : float
        Points per second; must be a whole number RflySim's three integers can make.
    lasers : int
    width : int, optional
        The DataWidth wanted (e.g. a fitted rosette's points per arc).

    Raises
    ------
    ConfigError
        If no W <= 5000, H <= 2000, F <= 1000 make the rate exactly.
    """
    whole = round(rate)
    if not math.isfinite(rate) or whole < 1 or abs(rate - whole) > 1e-6 * rate:
        raise ConfigError(f"a rate of {quoted(rate)} points/s; RflySim's DataWidth x DataHeight x DataCheckFreq makes "
                          "whole numbers of points per second only")
    limits = (PARAM_RANGES["data_width"].high, PARAM_RANGES["data_height"].high, PARAM_RANGES["data_check_freq"].high)
    best: tuple[tuple[float, ...], tuple[int, int, int]] | None = None
    for freq in range(1, int(limits[2]) + 1):
        frame, rest = divmod(whole, freq)
        if rest or frame > limits[0] * limits[1]:
            continue
        target = width or max(1, frame // 40)
        widths = [w for w in _divisors(frame) if w <= limits[0] and frame // w <= limits[1]]
        if not widths:
            continue
        w = min(widths, key=lambda w: (abs(w - target), w))
        key = (frame % lasers != 0, abs(math.log(freq / 10.0)), abs(w - target))
        if best is None or key < best[0]:
            best = (key, (w, frame // w, freq))
    if best is None:
        raise ConfigError(f"{whole:,} points/s cannot be made as DataWidth x DataHeight x DataCheckFreq within "
                          f"{int(limits[0])} x {int(limits[1])} x {int(limits[2])}")
    return best[1]


def _divisors(number: int) -> list[int]:
    small = [d for d in range(1, math.isqrt(number) + 1) if number % d == 0]
    return sorted(set(small + [number // d for d in small]))


@functools.lru_cache(maxsize=1)
def mid360_track() -> tuple[TrackParams, FieldOfView]:
    """The track and field of view RflySim's TypeID 23 (the Mid-360) is scanned with: the shipped
    ``livox_mid360`` preset's (fitted to Livox's public Mid-360 table)."""
    path = shipped_preset_dir() / f"{MID360_PRESET}.json"
    data = read_json_file(path)
    if not isinstance(data, Mapping) or TRACK_KEY not in data or FOV_KEY not in data:
        raise ConfigError(f"{path}: the shipped Mid-360 preset has no {TRACK_KEY} and {FOV_KEY}")
    return TrackParams.from_json(data[TRACK_KEY]), FieldOfView.from_json(data[FOV_KEY])


@functools.lru_cache(maxsize=64)
def _cone(camera_fov: float) -> FieldOfView:
    return FieldOfView.cone(camera_fov / 2.0)


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _check_int(spec: ParamRange, value: Any) -> None:
    if not _is_int(value):
        raise ConfigError(f"{spec.name} ({spec.label}) = {quoted(value)}; allowed: {spec.describe()}")
    spec.check(value)


#: The largest float32: RflySim reads the mount's numbers (and ``request`` sends them) as 32-bit floats.
FLOAT32_MAX = 3.4028234663852886e38


def _check_finite(name: str, value: Any) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(f"{name} = {quoted(value)}; allowed: a finite number")


def _check_float32(name: str, values: tuple[float, ...]) -> None:
    """Numbers that RflySim's float32 holds: 1e300 passed ``info`` and ``save`` here, then failed ``request`` with
    a traceback ("float too large to pack with f format"). (The other fields' own ranges are narrower.)"""
    for index, value in enumerate(values):
        if abs(value) > FLOAT32_MAX:
            raise ConfigError(f"{name}[{index}] = {quoted(value)} does not fit the 32-bit float RflySim reads it as; "
                              f"allowed: a number within +-{FLOAT32_MAX:.4g}")


def _check_vector(name: str, values: Any, length: int) -> None:
    if len(values) != length:
        raise ConfigError(f"{name} has {len(values)} values; allowed: {length} finite numbers")
    for index, value in enumerate(values):
        _check_finite(f"{name}[{index}]", value)


def _json_number(value: float) -> int | float:
    """Write whole numbers as JSON integers (600, not 600.0), as RflySim's files do."""
    return int(value) if float(value).is_integer() and abs(value) < 2**53 else float(value)


def _is_livox_entry(sensor: Any) -> bool:
    """A ``VisionSensors`` entry that is a Livox lidar: TypeID 6 of the v2 form, or 22 or 23 (6 with
    ``EularOrQuat`` is SDK v3's sound sensor)."""
    if not isinstance(sensor, Mapping):
        return False
    type_id = sensor.get("TypeID")
    if type_id == LIVOX_TYPE_ID:
        return EULAR_OR_QUAT_KEY not in sensor
    return type_id in LIVOX_TYPE_IDS["v3"]


def select_sensor(data: Any, seq_id: int | None = None) -> Mapping[str, Any]:
    """Pick the Livox sensor object out of a single object or a ``Config.json``.

    Parameters
    ----------
    data : dict
        Either one sensor object, or ``{"VisionSensors": [...]}``.
    seq_id : int, optional
        The ``SeqID`` to choose; default the first Livox entry (TypeID 6 of SDK v2, 22 or 23 of SDK v3).
    """
    livox_ids = f"TypeID {LIVOX_TYPE_ID}, {V3_ROSETTE_TYPE_ID} or {V3_MID360_TYPE_ID}"
    if isinstance(data, Mapping) and "VisionSensors" in data:
        sensors = data["VisionSensors"]
        if not isinstance(sensors, list):
            raise ConfigError("VisionSensors must be a JSON list of sensor objects")
        livox = [s for s in sensors if _is_livox_entry(s)]
        if seq_id is not None:
            chosen = [s for s in livox if s.get("SeqID") == seq_id]
            if not chosen:
                there = ", ".join(str(s.get("SeqID")) for s in livox) or "none"
                raise ConfigError(f"no Livox sensor with SeqID {seq_id} in VisionSensors; allowed: a SeqID of "
                                  f"its Livox sensors, {livox_ids} ({there})")
            livox = chosen
        if not livox:
            found = sorted({s.get("TypeID") for s in sensors if isinstance(s, Mapping)}, key=str)
            raise ConfigError(
                f"VisionSensors holds no Livox sensor ({livox_ids}; 6 only without {EULAR_OR_QUAT_KEY}); "
                f"TypeIDs found: {found or 'none'}"
            )
        return livox[0]
    if seq_id is not None and isinstance(data, Mapping) and data.get("SeqID") != seq_id:
        raise ConfigError(f"the sensor object has SeqID {quoted(data.get('SeqID'))}, not {seq_id}")
    return data


def load_config(path: str | os.PathLike[str], seq_id: int | None = None) -> SensorConfig:
    """Load a sensor configuration from a JSON file (one sensor object or a Config.json).

    Parameters
    ----------
    path : path-like
        The JSON file.
    seq_id : int, optional
        Which sensor of a ``Config.json``; default the first Livox one (TypeID 6, 22 or 23).
    """
    data = read_json_file(path)
    try:
        return SensorConfig.from_json_dict(select_sensor(data, seq_id))
    except ConfigError as exc:
        raise ConfigError(f"{Path(path).name}: {exc}") from None


def save_config(config: SensorConfig, path: str | os.PathLike[str]) -> None:
    """Save a configuration as a single RflySim sensor object, atomically."""
    write_text_atomic(path, dumps_readable(config.to_json_dict()))
