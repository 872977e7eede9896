"""Commands that hold the model against measured patterns: ``fit`` and ``compare``."""

from __future__ import annotations

import argparse
import json

from ..atomic import write_text_atomic
from ..fit import compare, fit_reference, plot_comparison
from ..presets import DESCRIPTION_KEY
from ..reference import load_reference
from .common import Command, add_config_arguments, add_seed_argument, config_from_args, config_label, positive_float


def cmd_fit(args: argparse.Namespace) -> int:
    reference = load_reference(args.reference, rate=args.rate)
    result = fit_reference(reference)
    cfg, shape, structure = result.config, result.shape, result.structure
    print(f"{reference.name}: {len(reference.t):,} points, {reference.seconds:g} s, {shape.petals} petals")
    print(f"  CameraFOV        {cfg.camera_fov:10.4f} deg")
    print(f"  otherParams[1] h {cfg.petal_height:10.4f} deg")
    print(f"  otherParams[2] p {cfg.spacing_exponent:10.4f}")
    print(f"  otherParams[3] q {cfg.tip_exponent:10.4f}")
    print(f"  otherParams[4]   {cfg.figure8_per_flower:10d}  figure-8s per flower   ({structure.method})")
    print(f"  otherParams[5]   {cfg.flowers_per_figure:10d}  flowers per figure")
    print(f"  otherParams[6]   {cfg.jitter_max_deg:10.4f} deg jitter after each {cfg.jitter_scope}")
    print(f"  DataWidth/Height/CheckFreq {cfg.data_width}/{cfg.data_height}/{cfg.data_check_freq} "
          f"(measured {shape.points_per_arc:.2f} points per arc)")
    print(f"  shape residual   rms {shape.rms_deg:.4f} deg, p95 {shape.p95_deg:.4f} deg (perpendicular distance)")
    print("  coverage         integration s   reference %   fit %")
    rows = []
    for t, ref, fit in zip(result.seconds, result.coverage_reference, result.coverage_fit, strict=True):
        print(f"                   {t:13g}   {100 * ref:11.2f}   {100 * fit:5.2f}")
        rows.append(f"{t:g} s {100 * ref:.1f}/{100 * fit:.1f} %")
    if args.out:
        data = cfg.to_json_dict()
        data[DESCRIPTION_KEY] = (
            f"Fitted to {reference.name} ({reference.seconds:g} s): shape residual rms {shape.rms_deg:.3f} deg, "
            f"p95 {shape.p95_deg:.3f} deg; coverage reference/fit {', '.join(rows)}"
        )
        write_text_atomic(args.out, json.dumps(data, indent=2) + "\n")
        print(f"wrote {args.out}")
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    cfg = config_from_args(args)
    reference = load_reference(args.reference, rate=args.rate)
    result = compare(cfg, reference, seed=args.seed)
    print(f"{config_label(args)} against {reference.name} ({reference.seconds:g} s)")
    print("  integration s   reference %   ours %   difference pp")
    for t, ref, ours in zip(result.seconds, result.coverage_reference, result.coverage_ours, strict=True):
        print(f"  {t:13g}   {100 * ref:11.2f}   {100 * ours:6.2f}   {100 * (ours - ref):+13.2f}")
    print("  radial density, million points per sr per s")
    print("  alpha deg      reference      ours")
    edges = result.density_edges_deg
    for k in range(0, len(result.density_ours), max(1, len(result.density_ours) // 10)):
        print(f"  {edges[k]:5.1f}-{edges[k + 1]:<5.1f}  {result.density_reference[k] / 1e6:9.3f}  "
              f"{result.density_ours[k] / 1e6:9.3f}")
    if args.plot:
        plot_comparison(result, args.plot, f"{config_label(args)} vs {reference.name}")
        print(f"wrote {args.plot}")
    return 0




def _fit_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("reference", help="measured pattern: .npy [theta, phi] radians or Livox CSV (degrees)")
    parser.add_argument("--rate", type=positive_float, default=100_000.0, help="points per second (default 100000)")
    parser.add_argument("--out", help="write the fitted preset JSON here")


def _compare_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    parser.add_argument("reference", help="measured pattern: .npy or Livox CSV")
    parser.add_argument("--rate", type=positive_float, default=100_000.0, help="points per second (default 100000)")
    add_seed_argument(parser)
    parser.add_argument("--plot", help="write a PNG plot of both curves and their difference")


COMMANDS: tuple[Command, ...] = (
    Command("fit", cmd_fit, "fit the model's parameters to a measured pattern and write a preset",
            "livox-viz fit ../shared/reference/mid40.npy --out presets/livox_mid40.json", _fit_arguments),
    Command("compare", cmd_compare, "coverage and radial density of a preset against a measured pattern",
            "livox-viz compare --preset livox_mid40 ../shared/reference/mid40.npy --plot compare.png",
            _compare_arguments),
)
