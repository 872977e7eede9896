"""Make the shipped presets of the Livox sensors: livox_horizon, livox_mid360, livox_hap, livox_avia, livox_tele15.

    .venv/bin/python scripts/make_sensor_presets.py [--tables DIR] [--out presets]

``--tables DIR`` names a folder holding the public 4 s ``horizon.npy`` and
``mid360.npy`` (rates 240 000 and 200 000 rows/s); without it the shipped first
seconds in ``presets/tables`` are used (the shipped presets were made from the
4 s tables: their frequencies are pinned four times closer).

- **Horizon, Mid-360**: ``fit_track`` on the table; the RflySim fields carry the
  best rosette ``fit_reference`` finds on the track (the Horizon) or a stand-in
  where none fits (the Mid-360 looks all around; a rosette looks one way).
- **HAP** (no public table here): the Horizon's fitted track stretched in azimuth
  from its 81.7 deg to the HAP's 120 deg, at the HAP's 452 000 pts/s, fitted
  again as a track; its rosette fitted like the Horizon's.
- **Avia, Tele-15** (no public table here): two-prism heads (risley.md section 2)
  built from the fitted Mid-70 / Mid-40 prism pairs: six lasers offset along y so
  the union spans the published 70.4 x 77.2 / 14.5 x 16.2 deg, at 240 000 pts/s;
  their rosettes are the fitted Mid-70 / Mid-40 rosettes at that rate.

Ranges are the longest Livox publishes for each (80 % reflectivity; the HAP's
manual gives 150 m at 10 %). Each carries its sheet's datasheet return model
(``LivoxVizReturns``, :data:`~livox_viz.config.returns_params.DATASHEETS`).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from livox_viz.config.fov import FieldOfView  # noqa: E402
from livox_viz.config.presets import DESCRIPTION_KEY, load_preset  # noqa: E402
from livox_viz.config.returns_params import DATASHEETS, describe_sheet  # noqa: E402
from livox_viz.config.risley_params import RisleyParams  # noqa: E402
from livox_viz.config.sensor import SensorConfig, frame_layout  # noqa: E402
from livox_viz.core.atomic import write_text_atomic  # noqa: E402
from livox_viz.core.jsonfile import dumps_readable  # noqa: E402
from livox_viz.fitting.reference import ReferencePattern, load_reference, pattern_table, xy_from_zup  # noqa: E402
from livox_viz.fitting.risley_fit import track_residual  # noqa: E402
from livox_viz.fitting.rosette_fit import fit_reference  # noqa: E402
from livox_viz.fitting.track_fit import fit_track  # noqa: E402
from livox_viz.patterns.factory import make_pattern  # noqa: E402
from livox_viz.patterns.planes import directions_from_xy  # noqa: E402


def write(config: SensorConfig, description: str, folder: Path, name: str) -> None:
    """Write the preset with its sensor's datasheet return model (``LivoxVizReturns``), said in its description."""
    sheet = name.removeprefix("livox_")
    config = replace(config, returns=DATASHEETS[sheet])
    data = config.to_json_dict()
    data[DESCRIPTION_KEY] = f"{description}. Returns: the {describe_sheet(sheet)}"
    write_text_atomic(folder / f"{name}.json", dumps_readable(data))
    print(f"{name}: {description}")


def with_rosette(track_config: SensorConfig, name: str) -> tuple[SensorConfig, str]:
    """The track configuration with the RflySim fields of the best rosette fitted to its first 4 s."""
    table = pattern_table(track_config, name, 4.0)
    result = fit_reference(table, base=track_config.with_pattern_model("rflysim"))
    rosette = result.config
    width, height, freq = frame_layout(track_config.point_rate, track_config.lasers, width=rosette.data_width)
    config = replace(track_config, camera_fov=rosette.camera_fov, other_params=(track_config.range_max,
                     *rosette.other_params[1:]), data_width=width, data_height=height, data_check_freq=freq,
                     jitter_scope=rosette.jitter_scope)
    return config, f"the best rosette, {result.shape.rms_deg:.2g} deg rms off its petals"


def fitted(table: ReferencePattern, base: SensorConfig, range_m: float, tolerance: float) -> tuple:
    fit = fit_track(table, tolerance_deg=tolerance)
    width, height, freq = frame_layout(table.rate, fit.params.lasers)
    config = replace(base, track=fit.params, fov=fit.field_of_view, pattern_model="track", data_width=width,
                     data_height=height, data_check_freq=freq,
                     other_params=(range_m, *base.other_params[1:]))
    return fit, config


def horizon(tables: Path | None, folder: Path) -> SensorConfig:
    table = load_reference(tables / "horizon.npy", rate=240_000) if tables else load_reference("horizon")
    fit, config = fitted(table, SensorConfig(), 260.0, 1e-3)
    config, rosette = with_rosette(config, "livox_horizon")
    write(config, f"Livox Horizon: 6 lasers, 240 000 pts/s, 81.7 x 25.1 deg, 260 m; track fitted to the public "
                  f"{table.seconds:g} s table ({len(fit.params.terms)} terms, rms {fit.rms_deg:.2g} deg between rays); "
                  f"RflySim fields: {rosette} (a rosette cannot draw a band)", folder, "livox_horizon")
    return config


def mid360(tables: Path | None, folder: Path) -> None:
    table = load_reference(tables / "mid360.npy", rate=200_000) if tables else load_reference("mid360")
    fit, config = fitted(table, load_preset("livox_mid70"), 70.0, 3e-3)
    write(config, f"Livox Mid-360: 4 lasers, 200 000 pts/s, 360 x 59 deg (elevation -7 to 52), 70 m; spin track "
                  f"fitted to the public {table.seconds:g} s table ({len(fit.params.terms)} terms, rms "
                  f"{fit.rms_deg:.2g} deg between rays, the table's own 0.01 deg print step); RflySim fields: a "
                  "stand-in (the seed's Mid-70 rosette): no rosette fits a head that sees all around",
          folder, "livox_mid360")


def hap(horizon_config: SensorConfig, folder: Path) -> None:
    rate, seconds = 452_000, 4.0
    k = np.arange(int(rate * seconds))
    source = replace(horizon_config, data_width=1130, data_height=40, data_check_freq=10)
    xy = make_pattern(source).take(k.size).xy_deg
    # Stretch the azimuth, keep the elevation: through the rays (x forward, y right, z down).
    d = directions_from_xy(xy)
    azimuth = np.arctan2(d[:, 1], d[:, 0]) * (120.0 / 81.7)
    elevation = -np.arcsin(np.clip(d[:, 2], -1, 1))
    stretched, _ = xy_from_zup(-azimuth, elevation, "boresight")
    table = ReferencePattern("hap", stretched, k / rate, float(rate))
    fit, config = fitted(table, SensorConfig(), 150.0, 1e-3)
    config, rosette = with_rosette(config, "livox_hap")
    write(config, f"Livox HAP: 6 lasers (assumed, as the Horizon), 452 000 pts/s, 120 x 25 deg, 150 m; NOT fitted "
                  f"to a table: the Horizon's fitted track stretched to 120 deg of azimuth ({len(fit.params.terms)} "
                  f"terms, {fit.rms_deg:.2g} deg rms from the stretch); RflySim fields: {rosette}", folder, "livox_hap")


def two_prism(base_preset: str, rosette_preset: str, width_deg: float, height_deg: float, range_m: float,
              name: str, sensor: str, folder: Path) -> None:
    """Six lasers on one prism pair, offset along y so that their union spans width x height."""
    pair = {"livox_mid70_risley": "Mid-70", "livox_mid40_risley": "Mid-40"}[base_preset]
    base = load_preset(base_preset).risley
    rosette = load_preset(rosette_preset)
    # The prism deflections that make one laser's track reach width / 2 (each term scales by its order).
    scale = 1.0
    for _ in range(4):
        trial = replace(base, deflection_deg=tuple(scale * d for d in base.deflection_deg))
        t = np.arange(100_000) / 100_000
        reach = float(np.abs(sum(c * np.exp(1j * (2 * np.pi * f * t + p)) for c, f, p in
                                 zip(trial.coefficients[0], trial.term_hz, trial.term_phase, strict=True))).max())
        scale *= (width_deg / 2) / reach
    scaled = replace(base, deflection_deg=tuple(scale * d for d in base.deflection_deg)).coefficients[0]
    offsets = np.linspace(-(height_deg - width_deg) / 2, (height_deg - width_deg) / 2, 6)
    terms = (*base.terms, (0, 0))
    coefficients = np.array([[*scaled, 1j * offset] for offset in offsets])
    params = RisleyParams(prism_hz=base.prism_hz, phase_rad=base.phase_rad, terms=terms,
                          base_coefficients=coefficients)
    ratio = width_deg / rosette.camera_fov
    config = replace(rosette, data_width=600, data_height=40, data_check_freq=10, camera_fov=round(width_deg, 4),
                     other_params=(range_m, round(rosette.petal_height * ratio, 4), *rosette.other_params[2:]),
                     risley=params, pattern_model="risley")
    xy = make_pattern(config).take(960_000).xy_deg
    # The field of view is the track's own outline: six offset circles make no ellipse.
    config = replace(config, fov=FieldOfView.of_points(xy))
    span = (np.ptp(xy[:, 0]), np.ptp(xy[:, 1]))
    write(config, f"Livox {sensor}: 6 lasers, 240 000 pts/s, {width_deg:g} x {height_deg:g} deg, {range_m:g} m; NOT "
                  f"fitted to a table: the fitted {pair} prism pair scaled to "
                  f"{width_deg:g} deg with six lasers {offsets[1] - offsets[0]:.2g} deg apart along y (the track spans "
                  f"{span[0]:.1f} x {span[1]:.1f} deg; prism speeds unpublished, the "
                  f"{pair}'s kept); RflySim fields: the "
                  f"{rosette_preset} rosette at this rate", folder, name)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tables", type=Path, help="folder of the public 4 s horizon.npy and mid360.npy")
    parser.add_argument("--out", type=Path, default=ROOT / "presets")
    args = parser.parse_args()
    horizon_config = horizon(args.tables, args.out)
    mid360(args.tables, args.out)
    hap(horizon_config, args.out)
    two_prism("livox_mid70_risley", "livox_mid70_fitted", 70.4, 77.2, 450.0, "livox_avia", "Avia", args.out)
    two_prism("livox_mid40_risley", "livox_mid40", 14.5, 16.2, 500.0, "livox_tele15", "Tele-15", args.out)
    for name in ("livox_horizon", "livox_mid360"):
        config = load_preset(args.out / f"{name}.json")
        table = load_reference(name.split("_")[1])
        ours = make_pattern(config).take(len(table.t)).xy_deg
        rms, p95, worst = track_residual(ours, table.xy_deg, config.pattern_plane)
        print(f"  {name} against the shipped {table.seconds:g} s: rms {rms:.2g}, p95 {p95:.2g}, max {worst:.2g} deg")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
