"""Which parameters the panel shows, per pattern model and page (names only: the panel builds the controls).

The pattern's own parameters come first (the rosette's RflySim ``otherParams``
and ``CameraFOV``; the Risley prisms; the track's two base rates), or, on the
returns page (``t``, and whenever ``d`` turns the datasheet model on), the
return model's sheet: range noise (1 sigma at the sheet's first range),
detection range at 10 % reflectivity, blind zone, beam divergence, false
alarms and angular noise (1 sigma). The frame structure (W x H x F, which sets
the point rate) is always shown.
"""

from __future__ import annotations

#: The pattern's parameters, per pattern model, in the panel's order.
PATTERN_PARAMS: dict[str, tuple[str, ...]] = {
    "rflysim": ("camera_fov", "petal_height", "spacing_exponent", "tip_exponent", "figure8_per_flower",
                "flowers_per_figure", "jitter_max_deg", "range_max"),
    "risley": ("prism_rpm_a", "prism_rpm_b", "deflection_a", "deflection_b", "laser_spacing", "camera_fov",
               "range_max"),
    "track": ("base_rpm_a", "base_rpm_b", "range_max"),
}
#: The return model's sheet (the returns page).
RETURN_PARAMS: tuple[str, ...] = ("returns_range_sigma", "returns_detection_range_10", "returns_blind_zone",
                                  "returns_false_alarm_rate", "returns_divergence_h", "returns_divergence_v",
                                  "returns_angular_sigma")
#: The frame structure, which sets the point rate W x H x F.
FRAME_PARAMS: tuple[str, ...] = ("data_width", "data_height", "data_check_freq")


def frame_params(config) -> tuple[str, ...]:
    """The frame parameters that act on ``config``: RflySim's Mid-360 (TypeID 23) has its own 64 x 272-point frame,
    so only its frame rate does."""
    from livox_viz.config.sensor import V3_MID360_TYPE_ID

    return ("data_check_freq",) if config.type_id == V3_MID360_TYPE_ID else FRAME_PARAMS
