"""Make the shipped presets of the Livox sensors: livox_horizon, livox_mid360, livox_avia, livox_tele15, livox_hap.

    .venv/bin/python scripts/make_sensor_presets.py [--tables DIR] [--out presets]

``--tables DIR`` names a folder holding the public 4 s tables ``horizon.npy``,
``mid360.npy``, ``avia.npy`` and ``tele15.npy`` (rates 240 000, 200 000, 240 000
and 240 000 rows/s); without it the shipped first seconds in ``presets/tables``
are used (the shipped presets were made from the 4 s tables: their frequencies
are pinned four times closer).

- **Horizon, Mid-360, Avia**: ``fit_track`` on the table; the RflySim fields
  carry the best rosette ``fit_reference`` finds on the track (Horizon, Avia)
  or a stand-in where none fits (the Mid-360 looks all around; a rosette looks
  one way). The Avia is fitted to 3e-4 deg (its track then replays the table
  within 1e-3 deg over any second of it); ``fit_risley``'s fixed term families
  leave 5e-3 deg on it.
- **Tele-15**: ``fit_risley`` on the table (a two-prism head: 16 terms follow it
  to 1e-5 deg, with the prism speed, deflection and spacing sliders); its
  RflySim fields carry the best rosette fitted to its track.
- **HAP** (no public table here): the Horizon's fitted track stretched in azimuth
  from its 81.7 deg to the HAP's 120 deg, at the HAP's 452 000 pts/s, fitted
  again as a track; its rosette fitted like the Horizon's. A guess, said so in
  its description.

Ranges are the longest Livox publishes for each (80 % reflectivity; the HAP's
manual gives 150 m at 10 %). Each carries its sheet's datasheet return model
(``LivoxVizReturns``, :data:`~livox_viz.config.returns_params.DATASHEETS`).
Every fit decides by counts, never by the clock: the same tables give the same
presets, bit for bit.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from livox_viz.config.presets import DESCRIPTION_KEY, load_preset  # noqa: E402
from livox_viz.config.returns_params import DATASHEETS, describe_sheet  # noqa: E402
from livox_viz.config.sensor import SensorConfig, frame_layout  # noqa: E402
from livox_viz.core.atomic import write_text_atomic  # noqa: E402
from livox_viz.core.jsonfile import dumps_readable  # noqa: E402
from livox_viz.fitting.reference import (  # noqa: E402
    ReferencePattern,
    load_reference,
    pattern_table,
    shipped_tables,
    xy_from_zup,
)
from livox_viz.fitting.risley_fit import fit_risley, track_residual  # noqa: E402
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


def public_table(tables: Path | None, name: str) -> ReferencePattern:
    """The public 4 s table ``name`` from ``tables`` at its shipped rate, else the shipped first second."""
    if tables is None:
        return load_reference(name)
    return load_reference(tables / f"{name}.npy", rate=float(shipped_tables()[name]["rate"]))


def fitted(table: ReferencePattern, base: SensorConfig, range_m: float, tolerance: float) -> tuple:
    fit = fit_track(table, tolerance_deg=tolerance)
    width, height, freq = frame_layout(table.rate, fit.params.lasers)
    config = replace(base, track=fit.params, fov=fit.field_of_view, pattern_model="track", data_width=width,
                     data_height=height, data_check_freq=freq,
                     other_params=(range_m, *base.other_params[1:]))
    return fit, config


def horizon(tables: Path | None, folder: Path) -> SensorConfig:
    table = public_table(tables, "horizon")
    fit, config = fitted(table, SensorConfig(), 260.0, 1e-3)
    config, rosette = with_rosette(config, "livox_horizon")
    write(config, f"Livox Horizon: 6 lasers, 240 000 pts/s, 81.7 x 25.1 deg, 260 m; track fitted to the public "
                  f"{table.seconds:g} s table ({len(fit.params.terms)} terms, rms {fit.rms_deg:.2g} deg between rays); "
                  f"RflySim fields: {rosette} (a rosette cannot draw a band)", folder, "livox_horizon")
    return config


def mid360(tables: Path | None, folder: Path) -> None:
    table = public_table(tables, "mid360")
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


def avia(tables: Path | None, folder: Path) -> None:
    table = public_table(tables, "avia")
    fit, config = fitted(table, SensorConfig(), 450.0, 3e-4)
    config, rosette = with_rosette(config, "livox_avia")
    write(config, f"Livox Avia: 6 lasers, 240 000 pts/s, 70.4 x 77.2 deg, 450 m; track fitted to the public "
                  f"{table.seconds:g} s table (prisms at {fit.params.base_rpm[0]:+.0f} and "
                  f"{fit.params.base_rpm[1]:+.0f} rpm, {len(fit.params.terms)} terms, rms {fit.rms_deg:.2g} deg "
                  f"between rays); RflySim fields: {rosette}", folder, "livox_avia")


def tele15(tables: Path | None, folder: Path) -> None:
    table = public_table(tables, "tele15")
    fit = fit_risley(table)
    width, height, freq = frame_layout(table.rate, fit.params.lasers)
    config = replace(SensorConfig(), risley=fit.params, pattern_model="risley", fov=table.field_of_view,
                     data_width=width, data_height=height, data_check_freq=freq,
                     other_params=(500.0, *SensorConfig().other_params[1:]))
    config, rosette = with_rosette(config, "livox_tele15")
    write(config, f"Livox Tele-15: 6 lasers, 240 000 pts/s, 14.5 x 16.2 deg, 500 m; Risley track fitted to the "
                  f"public {table.seconds:g} s table (prisms at {fit.params.prism_rpm[0]:+.0f} and "
                  f"{fit.params.prism_rpm[1]:+.0f} rpm, {len(fit.params.terms)} terms, rms {fit.rms_deg:.2g} deg "
                  f"between rays); RflySim fields: {rosette}", folder, "livox_tele15")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tables", type=Path,
                        help="folder of the public 4 s horizon.npy, mid360.npy, avia.npy and tele15.npy")
    parser.add_argument("--out", type=Path, default=ROOT / "presets")
    args = parser.parse_args()
    horizon_config = horizon(args.tables, args.out)
    mid360(args.tables, args.out)
    hap(horizon_config, args.out)
    avia(args.tables, args.out)
    tele15(args.tables, args.out)
    for name in ("livox_horizon", "livox_mid360", "livox_avia", "livox_tele15"):
        config = load_preset(args.out / f"{name}.json")
        table = load_reference(name.split("_")[1])
        ours = make_pattern(config).take(len(table.t)).xy_deg
        rms, p95, worst = track_residual(ours, table.xy_deg, config.pattern_plane)
        print(f"  {name} against the shipped {table.seconds:g} s: rms {rms:.2g}, p95 {p95:.2g}, max {worst:.2g} deg")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
