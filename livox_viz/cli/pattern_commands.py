"""Commands about the configuration and the pattern alone: ``info``, ``presets``, ``save``, ``pattern``,
``coverage``."""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path

import numpy as np

from livox_viz.casting.codec import max_decode_error
from livox_viz.config.presets import list_presets
from livox_viz.config.sensor import (
    EULER_KEY_RFLYSIM,
    MID360_PRESET,
    QUATERNION_KEY,
    V3_MID360_TYPE_ID,
    SensorConfig,
)
from livox_viz.core.atomic import atomic_path, make_work_dir
from livox_viz.core.errors import LivoxVizError, os_error_reason
from livox_viz.core.progress import Progress
from livox_viz.core.workload import check_points
from livox_viz.files.npzstream import NpzColumns
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.metrics import LIVOX_CELL_DEG, pattern_coverage
from livox_viz.patterns.stream import PatternStream, points_before

from .common import (
    Command,
    UsageError,
    add_config_arguments,
    add_sdk_argument,
    add_seed_argument,
    check_output_path,
    config_from_args,
    config_label,
    float_list,
    positive_float,
    write_config_json,
)

# info ----------------------------------------------------------------------------------
UNIT_TITLES = {"arc": "arc", "petal": "petal", "figure8": "figure-8", "flower": "flower", "figure": "figure",
               "frame": "frame"}


def derived_figures(cfg: SensorConfig) -> dict[str, float | int | str]:
    """The figures ``livox-viz info`` prints, by name."""
    rate = cfg.point_rate
    figures: dict[str, float | int | str] = {"point_rate_pts_per_s": rate, "pattern_model": cfg.pattern_model}
    for unit, points in cfg.unit_points.items():
        figures[f"points_per_{unit}"] = points
        figures[f"{unit}_s"] = points / rate
    if cfg.pattern_model == "rflysim":
        figures.update({
            "petals_per_flower": 2 * cfg.figure8_per_flower,
            "petal_spacing_deg": cfg.petal_spacing_deg,
            "flower_step_deg": cfg.flower_step_deg,
            "jitter_max_deg": cfg.jitter_max_deg,
            "jitter_scope": cfg.jitter_scope,
            "petal_length_deg": cfg.half_fov_deg,
            "petal_height_deg": cfg.petal_height,
        })
    elif cfg.pattern_model == "risley":
        risley = cfg.risley
        figures.update({
            "prism_rpm": list(risley.prism_rpm),
            "prism_deflection_deg": list(risley.deflection_deg),
            "lasers": risley.lasers,
            "series_terms": len(risley.terms),
        })
    else:
        track = cfg.track
        figures.update({
            "track_form": track.form,
            "base_rpm": list(track.base_rpm),
            "lasers": track.lasers,
            "series_terms": len(track.terms),
        })
    returns = cfg.return_params
    figures.update({
        "returns_model": returns.model,
        "returns_detection_range_m": [list(p) for p in returns.detection_range_m],
        "returns_range_sigma_m": [list(p) for p in returns.range_sigma_m],
        "returns_divergence_deg": list(returns.divergence_deg),
        "returns_blind_zone_m": returns.blind_zone_m,
        "returns_per_pulse": returns.returns_per_pulse,
        "returns_false_alarm_rate": returns.false_alarm_rate,
        "returns_angular_sigma_deg": returns.angular_sigma_deg,
    })
    fov = cfg.field_of_view
    figures.update({
        "pattern_plane": fov.plane,
        "fov_shape": fov.shape,
        "fov_size_deg": list(fov.size_deg),
        "fov_deg": cfg.camera_fov,
        "range_max_m": cfg.range_max,
        "range_step_m": cfg.range_step,
        "max_decode_error_m": max_decode_error(cfg.range_max),
        "mount_position_m": list(cfg.sensor_pos_xyz),
        "mount_angles_rad": list(cfg.sensor_ang_euler),
        "mount_angles_key": cfg.euler_key,
    })
    return figures


def cmd_info(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    figures = derived_figures(cfg)
    if args.json:
        print(json.dumps({"config": config_label(args), **figures}, indent=2))
        return 0
    model = {"risley": "Risley track", "track": "track"}.get(cfg.pattern_model, "rosette")
    if cfg.type_id == V3_MID360_TYPE_ID:
        model = f"Mid-360 ({MID360_PRESET}'s track unless the file has its own; RflySim's 64 x 272-point frame)"
    form = "v3 form: EularOrQuat, 16 otherParams" if cfg.v3_form else "old form: 8 otherParams"
    print(f"{config_label(args)}: Livox {model} (RflySim TypeID {cfg.type_id}, SDK {cfg.sdk}; {form}), "
          f"SeqID {cfg.seq_id}")
    fov = cfg.field_of_view
    if fov.shape == "cone":
        print(f"  field of view      {cfg.camera_fov:g} deg (cone of half-angle {cfg.half_fov_deg:g} deg)")
    else:
        print(f"  field of view      {fov.describe()} ({fov.plane} plane); the rosette's CameraFOV "
              f"{cfg.camera_fov:g} deg")
    print(f"  point rate         {cfg.point_rate:,} pts/s = "
          f"{cfg.data_width} x {cfg.data_height} x {cfg.data_check_freq} Hz")
    for unit, points in cfg.unit_points.items():
        print(f"  {UNIT_TITLES[unit]:<18} {points:>10,} pts  {points / cfg.point_rate * 1e3:10.3f} ms")
    if cfg.pattern_model == "rflysim":
        print(f"  petals per flower  {2 * cfg.figure8_per_flower}, {cfg.petal_spacing_deg:g} deg apart")
        print(f"  flower step        {cfg.flower_step_deg:g} deg, "
              f"+ U(0,1) x {cfg.jitter_max_deg:g} deg after each {cfg.jitter_scope}")
        print(f"  petal              length {cfg.half_fov_deg:g} deg, height h {cfg.petal_height:g} deg "
              f"(half its width), p = {cfg.spacing_exponent:g}, q = {cfg.tip_exponent:g}")
    elif cfg.pattern_model == "risley":
        risley = cfg.risley
        print(f"  prisms             {risley.prism_rpm[0]:+.1f} / {risley.prism_rpm[1]:+.1f} rpm, deflections "
              f"{risley.deflection_deg[0]:.3f} / {risley.deflection_deg[1]:.3f} deg")
        print(f"  series             {len(risley.terms)} terms, {risley.lasers} laser(s)")
    else:
        track = cfg.track
        print(f"  base speeds        {track.base_rpm[0]:+.1f} / {track.base_rpm[1]:+.1f} rpm"
              + (" (the first turns the azimuth)" if track.form == "spin" else ""))
        print(f"  series             {len(track.terms)} terms, {track.lasers} laser(s), {track.form} form")
    print(f"  range              {cfg.range_max:g} m, int16 step {cfg.range_step * 1e3:.3f} mm, "
          f"max decode error {max_decode_error(cfg.range_max) * 1e3:.3f} mm")
    # The mounting angles' key has two spellings: say which this file used (saving keeps it).
    spelling = "RflySim's spelling" if cfg.euler_key == EULER_KEY_RFLYSIM else "the original document's spelling"
    if cfg.mount_quaternion is not None:
        print(f"  mount              at {', '.join(f'{v:g}' for v in cfg.sensor_pos_xyz)} m (FRD of the body), "
              f"quaternion [w, x, y, z] {', '.join(f'{v:g}' for v in cfg.sensor_ang_quat or ())} "
              f"(EularOrQuat {cfg.eular_or_quat:g} > 0.5: {QUATERNION_KEY}, not {cfg.euler_key})")
    else:
        print(f"  mount              at {', '.join(f'{v:g}' for v in cfg.sensor_pos_xyz)} m (FRD of the body), "
              f"roll/pitch/yaw {', '.join(f'{v:g}' for v in cfg.sensor_ang_euler)} rad, read from {cfg.euler_key} "
              f"({spelling})")
    returns = cfg.return_params
    kind = {1: "single", 2: "dual", 3: "triple"}[returns.returns_per_pulse]
    sheet = (f"detection {', '.join(f'{r:g} m at {100 * p:g} %' for p, r in returns.detection_range_m)}; range "
             f"noise {', '.join(f'{100 * s:g} cm at {r:g} m' for r, s in returns.range_sigma_m)}; divergence "
             f"{returns.divergence_deg[0]:g} x {returns.divergence_deg[1]:g} deg; blind zone "
             f"{returns.blind_zone_m:g} m; {kind} return; false alarms {100 * returns.false_alarm_rate:g} %; "
             f"angular noise {returns.angular_sigma_deg:g} deg")
    if returns.model == "ideal":
        print("  returns            ideal (each ray's exact first hit, as RflySim computes); --returns datasheet: "
              f"{sheet}")
    else:
        print(f"  returns            datasheet: {sheet}")
    return 0


def _info_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    parser.add_argument("--json", action="store_true", help="print JSON")


# presets -------------------------------------------------------------------------------
def cmd_presets(args: argparse.Namespace) -> int:
    presets = list_presets()
    if args.json:
        print(json.dumps([{"name": p.name, "path": str(p.path), "description": p.description,
                           "shipped": p.shipped} for p in presets], indent=2))
        return 0
    width = max((len(p.name) for p in presets), default=10)
    for info in presets:
        origin = "" if info.shipped else "  [user]"
        print(f"{info.name:<{width}}  {info.description}{origin}")
    from livox_viz.config.presets import user_config_dir

    print(f"\nyour presets: {user_config_dir('presets')} (the window's p saves there); your meshes for the window's "
          f"m: {user_config_dir('scenes')}")
    return 0


def _presets_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON")


# pattern -------------------------------------------------------------------------------
def cmd_pattern(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    out = check_output_path(args.out, (".npz", ".csv"))
    total = points_before(args.seconds, cfg.point_rate)
    check_points(total, f"pattern --seconds {args.seconds:g}", force=args.force)
    pattern = make_pattern(cfg, seed=args.seed)
    progress = Progress(f"pattern -> {out.name}", args.seconds, "s")
    block = max(cfg.points_per_frame, 100_000)
    labels = list(pattern.take(0).labels())
    try:
        _write_pattern(out, pattern, total, block, labels, progress, cfg.point_rate)
    except OSError as exc:
        raise LivoxVizError(f"{out}: cannot write ({os_error_reason(exc)}); the old file, if any, is kept") from exc
    progress.close()
    print(f"wrote {total:,} points ({args.seconds:g} s, seed {args.seed}) to {out}")
    return 0


def _write_pattern(out: Path, pattern: PatternStream, total: int, block: int, labels: list[str], progress: Progress,
                   rate: float) -> None:
    """The ``total`` points of ``pattern`` into ``out`` (NPZ or CSV), ``block`` points at a time."""
    if out.suffix.lower() == ".npz":
        work = make_work_dir(out)
        try:
            columns = {"xy_deg": ("<f8", (2,)), "t": ("<f8", ())}
            columns.update({name: ("<i8", ()) for name in labels})
            table = NpzColumns(work, columns)
            try:
                while pattern.position < total:
                    chunk = pattern.take(min(block, total - pattern.position))
                    table.append({"xy_deg": chunk.xy_deg, "t": chunk.t, **chunk.labels()})
                    progress.update(chunk.stop / rate)
                with atomic_path(out) as tmp:
                    table.finish(tmp)
            finally:
                table.discard()  # closed by finish; after a failure, what its buffers could not write goes
        finally:
            import shutil

            shutil.rmtree(work, ignore_errors=True)
    else:
        with atomic_path(out) as tmp, open(tmp, "w", newline="", encoding="utf-8") as handle:
            csv.writer(handle).writerow(["x_deg", "y_deg", "t", *labels])
            while pattern.position < total:
                chunk = pattern.take(min(block, total - pattern.position))
                columns = [chunk.xy_deg[:, 0], chunk.xy_deg[:, 1], chunk.t, *chunk.labels().values()]
                np.savetxt(handle, np.column_stack(columns), fmt=["%.9g"] * 3 + ["%d"] * len(labels), delimiter=",")
                progress.update(chunk.stop / rate)


def _pattern_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    parser.add_argument("--seconds", type=positive_float, default=1.0, help="scan time to write (default 1)")
    add_seed_argument(parser)
    parser.add_argument("--out", required=True, help="output file, .npz or .csv")
    parser.add_argument("--force", action="store_true", help="allow more points than the documented budget")


# coverage ------------------------------------------------------------------------------
def cmd_coverage(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    smallest = min(cfg.field_of_view.size_deg) / 2
    if args.cell_deg > smallest:
        what = "the FOV's half-angle" if cfg.field_of_view.shape == "cone" else "half the FOV's smaller side"
        raise UsageError(f"--cell-deg {args.cell_deg:g} is larger than {what} {smallest:g} deg; allowed: up to "
                         f"{smallest:g}")
    fractions = pattern_coverage(cfg, args.seconds, cell_deg=args.cell_deg, seed=args.seed)
    if args.json:
        print(json.dumps({"config": config_label(args), "cell_deg": args.cell_deg, "seed": args.seed,
                          "coverage": [{"seconds": s, "fraction": float(f)}
                                       for s, f in zip(args.seconds, fractions, strict=True)]}, indent=2))
        return 0
    print(f"{config_label(args)}: FOV coverage, {args.cell_deg:g} deg cells, seed {args.seed}")
    print("  integration s   coverage %")
    for seconds, fraction in zip(args.seconds, fractions, strict=True):
        print(f"  {seconds:13g}   {100 * fraction:10.2f}")
    return 0


def _coverage_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    parser.add_argument("--seconds", type=float_list, default=[0.1, 0.5, 1.0, 2.0],
                        help="integration times, comma-separated (default 0.1,0.5,1,2)")
    parser.add_argument("--cell-deg", type=positive_float, default=LIVOX_CELL_DEG,
                        help=f"grid cell size in degrees (default {LIVOX_CELL_DEG:.4f} = 5 mrad)")
    add_seed_argument(parser)
    parser.add_argument("--json", action="store_true", help="print JSON")


# save ----------------------------------------------------------------------------------
def cmd_save(args: argparse.Namespace) -> int:
    check_output_path(args.out, (".json",))
    cfg = config_from_args(args)
    what = write_config_json(args.out, cfg, args.sdk)
    print(f"wrote {args.out} ({what})")
    return 0


def _save_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    add_sdk_argument(parser)
    parser.add_argument("--out", required=True, help="the sensor JSON to write (one RflySim sensor object)")


COMMANDS: tuple[Command, ...] = (
    Command("info", cmd_info, "print the derived figures of a sensor configuration",
            "livox-viz info --preset livox_mid70", _info_arguments),
    Command("presets", cmd_presets, "list the sensor presets", "livox-viz presets", _presets_arguments),
    Command("save", cmd_save, "write a preset or a sensor JSON for RflySim's SDK v2 or v3 (keys and order kept)",
            "livox-viz save --preset livox_mid70 --sdk v3 --out Config_v3.json", _save_arguments),
    Command("pattern", cmd_pattern, "write the scan pattern (angles, times, labels) to .npz or .csv",
            "livox-viz pattern --seconds 0.5 --seed 1 --out pattern.npz", _pattern_arguments),
    Command("coverage", cmd_coverage, "FOV coverage against integration time",
            "livox-viz coverage --seconds 0.1,0.5,1,2 --json", _coverage_arguments),
)
