"""Commands that hold a model against a measured pattern or another preset: ``fit`` and ``compare``."""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from livox_viz.config.fov import FieldOfView
from livox_viz.config.presets import DEFAULT_PRESET, DESCRIPTION_KEY, load_preset
from livox_viz.config.sensor import SensorConfig, frame_layout
from livox_viz.config.track_params import TrackParams
from livox_viz.core.errors import ConfigError
from livox_viz.files.frame_files import FRAME_SUFFIXES
from livox_viz.fitting.compare import compare
from livox_viz.fitting.plot import plot_comparison
from livox_viz.fitting.reference import ReferencePattern, is_table, load_table_or_preset, shipped_tables
from livox_viz.fitting.risley_fit import fit_risley
from livox_viz.fitting.rosette_fit import fit_reference
from livox_viz.fitting.track_fit import DEFAULT_TOLERANCE_DEG, MIN_TOLERANCE_DEG, TrackFit, fit_track

from .common import (
    Command,
    UsageError,
    add_config_arguments,
    add_sdk_argument,
    add_seed_argument,
    check_output_path,
    config_from_args,
    config_label,
    positive_float,
    whole_number,
    write_config_json,
)
from .fit_recording import (
    add_recording_arguments,
    check_recording_arguments,
    fit_recording_command,
    is_recording,
)

RATE_HELP = ("firings per second of a table (default: a shipped table's own, the rows' times in a CSV's Time/s "
             "or an .npz's t, else read off the spectrum: the rate at which the head's parts turn at whole rpm; "
             "the output says which)")


def _reference(args: argparse.Namespace) -> ReferencePattern:
    """``fit``'s target: a table file, or with ``--to`` a preset's own track."""
    if (args.reference is None) == (args.to is None):
        raise UsageError("give a table (REFERENCE) or --to PRESET, one of them")
    text = args.reference if args.reference is not None else args.to
    if args.to is not None and is_table(text):
        raise UsageError(f"--to {text}: allowed: a preset name or a sensor JSON (a table goes without --to)")
    return load_table_or_preset(text, rate=args.rate, seconds=args.seconds, seed=args.seed)


def _write_preset(args: argparse.Namespace, config: SensorConfig, description: str) -> None:
    what = write_config_json(args.out, config, args.sdk, {DESCRIPTION_KEY: description})
    print(f"wrote {args.out} ({what})")


def cmd_fit(args: argparse.Namespace) -> int:
    recording = args.reference is not None and is_recording(args.reference)
    if args.model is None:
        args.model = "recording" if recording else "rflysim"
    if args.model == "recording":
        if not recording:
            raise UsageError(f"--model recording takes a recorded frame ({', '.join(FRAME_SUFFIXES)}, a CSV with x, "
                             f"y, z); {args.reference or args.to} is not one")
        check_recording_arguments(args)
        if args.out:
            check_output_path(args.out, (".json",))
        return fit_recording_command(args)
    if args.out:
        check_output_path(args.out, (".json",))
    if args.sdk is not None and not args.out:
        raise UsageError("--sdk says which RflySim SDK the preset of --out is for; give --out too")
    if args.tolerance is not None and args.model != "track":
        raise UsageError("--tolerance goes with --model track")
    if args.tolerance is not None and not MIN_TOLERANCE_DEG <= args.tolerance <= 1.0:
        raise UsageError(f"--tolerance {args.tolerance:g}; allowed: {MIN_TOLERANCE_DEG:g} to 1 deg rms (a track is "
                         "computed to about 1e-9 deg)")
    if args.beams is not None and args.model == "rflysim":
        raise UsageError("--beams goes with --model risley or track (the rosette has one laser)")
    reference = _reference(args)
    if args.beams is not None:
        _check_groups(reference, args.beams)
    base, base_said = _base(args, reference)
    if args.model == "risley":
        return _fit_risley(args, reference, base, base_said)
    if args.model == "track":
        return _fit_track(args, reference, base, base_said)
    result = fit_reference(reference, base=base.with_pattern_model("rflysim"))
    cfg, shape, structure = result.config, result.shape, result.structure
    print(f"{reference.name}: {len(reference.t):,} points, {reference.seconds:g} s, {shape.petals} petals")
    print(_rate_line(reference))
    print(f"  base             {base_said}")
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
    rough = shape.rough_warning()
    if rough:
        print(f"  warning: {rough}")
    print("  coverage         integration s   reference %   fit %")
    rows = []
    for t, ref, fit in zip(result.seconds, result.coverage_reference, result.coverage_fit, strict=True):
        print(f"                   {t:13g}   {100 * ref:11.2f}   {100 * fit:5.2f}")
        rows.append(f"{t:g} s {100 * ref:.1f}/{100 * fit:.1f} %")
    if args.out:
        _write_preset(args, cfg, f"RflySim rosette fitted to {reference.name} ({reference.seconds:g} s): shape "
                                 f"residual rms {shape.rms_deg:.3f} deg, p95 {shape.p95_deg:.3f} deg; coverage "
                                 f"reference/fit {', '.join(rows)}")
    return 0


def _base(args: argparse.Namespace, reference: ReferencePattern) -> tuple[SensorConfig, str]:
    """The configuration whose RflySim fields a fitted preset keeps, and where it came from in words.

    ``--preset``/``--config`` when given; else the default preset's RflySim fields with the range and return
    sheet of the table's own sensor when the table is (or begins as) a shipped one; else the default preset,
    said plainly (its range and return sheet are the Mid-70's).
    """
    if getattr(args, "preset", None) or getattr(args, "config", None):
        return config_from_args(args), f"{config_label(args)} (its RflySim fields, range and return model)"
    default = config_from_args(args)
    entry = shipped_tables().get(reference.shipped) if reference.shipped else None
    if entry is not None and entry.get("preset"):
        sensor = load_preset(entry["preset"])
        returns = sensor.returns
        if returns is not None and args.model == "rflysim":  # RflySim's rosette presets stay ideal by default
            returns = replace(returns, model="ideal")
        base = replace(default, other_params=(sensor.range_max, *default.other_params[1:]), returns=returns)
        return base, (f"{DEFAULT_PRESET}'s RflySim fields with the range ({sensor.range_max:g} m) and return model of "
                      f"{entry['preset']}, the {entry.get('sensor', 'table')}'s (--preset NAME to take another's)")
    return default, (f"{DEFAULT_PRESET}, the default (its RflySim fields, its {default.range_max:g} m range and the "
                     "Mid-70's return sheet): --preset NAME takes your sensor's")


def _check_groups(reference: ReferencePattern, lasers: int) -> None:
    """Refuse, before the fit, a laser count whose firing groups no frame at the table's rate holds whole."""
    def whole(count: int) -> bool:
        try:
            width, height, _ = frame_layout(reference.rate, count)
        except ConfigError:
            return False
        return (width * height) % count == 0

    if not whole(lasers):
        allowed = ", ".join(str(k) for k in range(1, 17) if whole(k))
        raise UsageError(f"--beams {lasers}: at {reference.rate:,.6g} rows/s no frame (DataWidth x DataHeight, "
                         f"DataCheckFreq 1 to 1000 a second) holds whole groups of {lasers} lasers; allowed here: "
                         f"{allowed or 'none'}")


def _rate_line(reference: ReferencePattern) -> str:
    """Where the table's rate came from, and how many rows it missed."""
    missing = reference.firings - len(reference.t)
    gaps = f", {missing:,} firings without a row" if missing else ""
    return f"  rate             {reference.rate:,.6g} rows/s: {reference.rate_source}{gaps}"


def _at_table_rate(base: SensorConfig, reference: ReferencePattern, lasers: int, found: int) -> SensorConfig:
    """The base configuration with W x H x F equal to the table's rows per second (about 10 frames/s), each frame
    whole firing groups of ``lasers`` where any frame at that rate is.

    The base's own layout is kept when it already makes the rate; otherwise W stays nearest the base's. A rate
    no frame of whole groups makes (the HAP's 452 000 rows/s has no factor 3: no frame holds whole groups of its
    6 lasers) is kept when the rows' geometry found that many lasers: its frames begin on any laser, as the
    head's own do (:func:`_frame_note` says so).

    Raises
    ------
    UsageError
        When no frame of whole groups makes the rate for a forced ``--beams`` the rows do not show.
    """
    if base.point_rate == reference.rate and base.points_per_frame % lasers == 0:
        return base
    width, height, freq = frame_layout(reference.rate, lasers, width=base.data_width)
    if (width * height) % lasers and lasers != found:
        blame = (f"; --beams {lasers} where the rows' geometry says {found}: leave --beams out" if lasers != found
                 else "")
        raise UsageError(f"{reference.name}: at {reference.rate:,.6g} rows/s no frame (DataWidth x DataHeight, "
                         f"DataCheckFreq 1 to 1000 a second) holds whole groups of {lasers} lasers{blame}")
    return replace(base, data_width=width, data_height=height, data_check_freq=freq)


def _frame_note(config: SensorConfig, lasers: int) -> str | None:
    """A line for a layout whose frames hold no whole firing groups (each frame may then begin on any laser)."""
    if config.points_per_frame % lasers == 0:
        return None
    return (f"  frames           {config.points_per_frame:,} points hold no whole groups of {lasers} lasers (no frame "
            f"at {config.point_rate:,} pts/s does): a frame may begin on any laser")


def _with_track(config: SensorConfig, track: TrackParams, fov: FieldOfView) -> SensorConfig:
    """The track and its field of view; a round field of view is also the rosette's CameraFOV."""
    if fov.shape == "cone":
        return replace(config, track=track, pattern_model="track", fov=fov,
                       camera_fov=round(2 * fov.half_angle_deg, 4))
    return replace(config, track=track, pattern_model="track", fov=fov)


def _fit_risley(args: argparse.Namespace, reference: ReferencePattern, base: SensorConfig, base_said: str) -> int:
    fit = fit_risley(reference, beams=args.beams)
    params = fit.params
    half_fov = float(np.hypot(reference.xy_deg[:, 0], reference.xy_deg[:, 1]).max())
    base = _at_table_rate(base, reference, params.lasers, fit.lasers_found)
    # The field of view the table covers (six offset circles make no cone: a cone would cap coverage).
    config = replace(base, risley=params, pattern_model="risley", camera_fov=round(2 * half_fov, 4),
                     fov=reference.field_of_view)
    rate = config.point_rate
    forced = "" if args.beams is None else f" (forced; the rows' geometry says {fit.lasers_found})"
    print(f"{reference.name}: {len(reference.t):,} rows, {reference.seconds:g} s at {reference.rate:g} rows/s")
    print(_rate_line(reference))
    print(f"  base             {base_said}")
    print(f"  lasers           {params.lasers}{forced}")
    print(f"  prism A          {params.prism_hz[0]:+.6f} Hz = {params.prism_rpm[0]:+.3f} rpm, "
          f"deflection {params.deflection_deg[0]:.5f} deg, phase {params.phase_rad[0]:+.6f} rad")
    print(f"  prism B          {params.prism_hz[1]:+.6f} Hz = {params.prism_rpm[1]:+.3f} rpm, "
          f"deflection {params.deflection_deg[1]:.5f} deg, phase {params.phase_rad[1]:+.6f} rad")
    print(f"  series           {len(params.terms)} terms: {' '.join(f'({m},{n})' for m, n in params.terms)}")
    print(f"  track residual   rms {fit.rms_deg:.6f} deg, p95 {fit.p95_deg:.6f} deg, max {fit.max_deg:.6f} deg "
          f"(sample for sample)")
    if params.lasers > 1:
        print("  per laser rms    " + " ".join(f"{v:.6f}" for v in fit.rms_per_laser_deg) + " deg")
    print(f"  field of view    {config.field_of_view.describe()}")
    print(f"  fitted in        {fit.seconds:.1f} s")
    print(f"  plays at         {config.data_width} x {config.data_height} x {config.data_check_freq} = {rate:,} "
          "pts/s, the table's rate")
    note = _frame_note(config, params.lasers)
    if note:
        print(note)
    _warn_forced(args, fit.lasers_found)
    if args.out:
        _write_preset(args, config, f"Risley track fitted to {reference.name} ({reference.seconds:g} s, "
                                    f"{params.lasers} laser{'s' if params.lasers > 1 else ''}): track residual rms "
                                    f"{fit.rms_deg:.2g} deg, p95 {fit.p95_deg:.2g} deg, max {fit.max_deg:.2g} deg "
                                    f"sample for sample")
    return 0


def _warn_forced(args: argparse.Namespace, found: int) -> None:
    if args.beams is not None and args.beams != found:
        print(f"  warning: --beams {args.beams} where the rows' geometry says {found}: the preset plays "
              f"{args.beams} lasers' tracks in turn; leave --beams out unless you know the head has {args.beams}")


def _fit_track(args: argparse.Namespace, reference: ReferencePattern, base: SensorConfig, base_said: str) -> int:
    tolerance = DEFAULT_TOLERANCE_DEG if args.tolerance is None else args.tolerance
    fit = fit_track(reference, beams=args.beams, tolerance_deg=tolerance)
    params = fit.params
    base = _at_table_rate(base, reference, params.lasers, fit.lasers_found)
    config = _with_track(base, params, fit.field_of_view)
    print(_track_report(reference, fit, args.beams is not None))
    print(f"  base             {base_said}")
    print(f"  plays at         {config.data_width} x {config.data_height} x {config.data_check_freq} = "
          f"{config.point_rate:,} pts/s, the table's rate")
    note = _frame_note(config, params.lasers)
    if note:
        print(note)
    _warn_forced(args, fit.lasers_found)
    if fit.rms_deg > 0.01:
        print(f"  warning: the track follows the table only to {fit.rms_deg:.3g} deg rms (more than 0.01 deg): "
              "is the table noisy, or its rows out of order?")
    if args.out:
        lasers = f"{params.lasers} laser{'s' if params.lasers > 1 else ''}"
        _write_preset(args, config, f"Track fitted to {reference.name} ({reference.seconds:g} s, {lasers}, "
                                    f"{len(params.terms)} terms, {params.form} form): residual rms "
                                    f"{fit.rms_deg:.2g} deg, p95 {fit.p95_deg:.2g} deg, max {fit.max_deg:.2g} deg "
                                    f"between rays; field of view {fit.field_of_view.describe()}")
    return 0


def _track_report(reference: ReferencePattern, fit: TrackFit, forced: bool) -> str:
    """What ``fit --model track`` prints: the track found and how well it replays the table."""
    params = fit.params
    orders_a = max(abs(m) for m, _ in params.terms)
    orders_b = max(abs(n) for _, n in params.terms)
    order = "in one fixed order" if fit.in_order else "out of order, each row's laser from the geometry"
    if fit.grouped:
        order += f" (listed in groups of {params.lasers} in no fixed order: each row at its group's time)"
    moved = f"; {fit.relabelled} rows moved to the laser whose track passes nearest" if fit.relabelled else ""
    lines = [f"{reference.name}: {len(reference.t):,} rows, {reference.seconds:g} s at {reference.rate:g} rows/s, "
             f"{reference.plane} plane",
             _rate_line(reference),
             f"  lasers           {params.lasers}" + (f" (forced; the rows' geometry says {fit.lasers_found})"
                                                    if forced else "") + f", {order}{moved}",
             f"  form             {params.form}" + (" (azimuth = A(t) + series, elevation = series)"
                                                    if params.form == "spin" else ""),
             f"  base A           {params.base_hz[0]:+.6f} Hz = {params.base_rpm[0]:+.3f} rpm",
             f"  base B           {params.base_hz[1]:+.6f} Hz = {params.base_rpm[1]:+.3f} rpm",
             f"  series           {len(params.terms)} terms, |m| <= {orders_a}, |l| <= {orders_b}",
             f"  residual         rms {fit.rms_deg:.6f} deg, p95 {fit.p95_deg:.6f} deg, max {fit.max_deg:.6f} deg "
             "(angle between each row's ray and the model's)"]
    if params.lasers > 1:
        lines.append("  per laser rms    " + " ".join(f"{v:.6f}" for v in fit.rms_per_laser_deg) + " deg")
    lines += [f"  field of view    {fit.field_of_view.describe()}",
              f"  fitted in        {fit.seconds:.1f} s"]
    lines += [f"  budget           {note}" for note in fit.budget_notes]
    return "\n".join(lines)


def _fit_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("reference", nargs="?", help="scan table: a shipped one by name (mid40, mid70, horizon, "
                                                     "mid360, avia, tele15), a .npy [theta, phi] in radians, an "
                                                     ".npz of theta, phi and t (seconds) or a Livox CSV (degrees); "
                                                     "rows may be out of laser order, with gaps, cut anywhere. Or "
                                                     "a real sensor's recording: a .pcd, .ply or x,y,z .csv frame "
                                                     "in firing order with its no-returns as (0, 0, 0), an .lvx2, "
                                                     ".lvx or a Livox driver's .bag")
    parser.add_argument("--to", help="fit to a preset's own track instead of a table, e.g. livox_mid70_risley")
    parser.add_argument("--model", choices=("rflysim", "risley", "track", "recording"), default=None,
                        help="rflysim: RflySim's rosette parameters (default for a table); risley: the two-prism "
                             "track; track: any head's track (oscillating or turning parts, 360-degree heads); "
                             "recording (default for a recorded frame): a head's track made the recording's "
                             "(mirror image, laser order, phases, motor speeds)")
    parser.add_argument("--beams", type=whole_number(1, 16), help="with --model risley or track: the number of "
                                                                  "lasers (default: read off the table's step "
                                                                  "pattern)")
    parser.add_argument("--tolerance", type=positive_float,
                        help=f"with --model track: the residual, deg rms, the series may leave when it prunes its "
                             f"terms ({MIN_TOLERANCE_DEG:g} to 1, default {DEFAULT_TOLERANCE_DEG:g}; fewer terms "
                             "stream faster)")
    parser.add_argument("--rate", type=positive_float, help=RATE_HELP)
    parser.add_argument("--seconds", type=positive_float, default=4.0,
                        help="with --to: how much of the preset's track to fit (default 4)")
    add_recording_arguments(parser)
    add_seed_argument(parser)
    add_config_arguments(parser)
    parser.add_argument("--out", help="write the fitted preset JSON here (RflySim fields from --preset/--config)")
    add_sdk_argument(parser)


#: A track residual against a recording above this (deg rms) is the sensor's phases, not ours: a twin fitted to its
#: recording (``fit RECORDING``) follows it to within a few hundredths of a degree.
RECORDING_ALIGNED_DEG = 0.1


def cmd_compare(args: argparse.Namespace) -> int:
    if args.plot:
        check_output_path(args.plot, (".png",))
    cfg = config_from_args(args)
    reference = load_table_or_preset(args.reference, rate=args.rate, seconds=args.seconds, seed=args.seed,
                                     recording_rate=float(cfg.point_rate))
    result = compare(cfg, reference, seed=args.seed)
    span = "" if result.span_seconds >= reference.seconds else f", its first {result.span_seconds:g} s compared"
    print(f"{config_label(args)} against {reference.name} ({reference.seconds:g} s{span})")
    if reference.recording:
        print(f"  the {reference.recording} recording's {len(reference.t):,} returns of {reference.firings:,} "
              f"firings ({1 - len(reference.t) / reference.firings:.1%} no-returns: its density counts returns); "
              f"rate {reference.rate:,.6g} rows/s: {reference.rate_source}")
    print("  integration s   reference %   ours %   difference pp")
    for t, ref, ours in zip(result.seconds, result.coverage_reference, result.coverage_ours, strict=True):
        print(f"  {t:13g}   {100 * ref:11.2f}   {100 * ours:6.2f}   {100 * (ours - ref):+13.2f}")
    print(f"  density along the {result.profile_label.split(',')[0]}, million points per sr per s")
    print("  deg            reference      ours")
    edges = result.density_edges_deg
    for k in range(0, len(result.density_ours), max(1, len(result.density_ours) // 10)):
        print(f"  {edges[k]:5.1f}-{edges[k + 1]:<5.1f}  {result.density_reference[k] / 1e6:9.3f}  "
              f"{result.density_ours[k] / 1e6:9.3f}")
    if result.track_residual is not None:
        rms, p95, worst = result.track_residual
        print(f"  track residual   rms {rms:.6f} deg, p95 {p95:.6f} deg, max {worst:.6f} deg (angle between rays, "
              "sample for sample)")
        if reference.recording and rms > RECORDING_ALIGNED_DEG:
            head = f"--config {args.config}" if getattr(args, "config", None) else f"--preset {config_label(args)}"
            print(f"                   the recording's sensor started at its own phases, ours at the preset's: align "
                  f"a twin first (livox-viz fit {args.reference} {head} --out twin.json), "
                  "then compare --config twin.json")
    else:
        print(f"  track residual   none: {result.no_residual_because}")
    if args.plot:
        plot_comparison(result, args.plot, f"{config_label(args)} vs {reference.name}")
        print(f"wrote {args.plot}")
    return 0


def _compare_arguments(parser: argparse.ArgumentParser) -> None:
    add_config_arguments(parser)
    parser.add_argument("reference", help="a scan table (a shipped one by name, a .npy, an .npz or a Livox CSV), a "
                                          "real sensor's recording (.pcd, .ply, a CSV of x, y, z, .lvx2, .lvx, "
                                          ".bag: rows in firing order, no-returns as 0,0,0; without per-point times "
                                          "at the preset's point rate) or a preset (name or JSON)")
    parser.add_argument("--rate", type=positive_float, help=RATE_HELP)
    parser.add_argument("--seconds", type=positive_float, default=4.0,
                        help="how much of a preset reference to replay (default 4)")
    add_seed_argument(parser)
    parser.add_argument("--plot", help="write a PNG plot of both curves and their difference")


COMMANDS: tuple[Command, ...] = (
    Command("fit", cmd_fit, "fit a pattern model's parameters to a measured table or a preset's track, or a "
                            "head's track to a real sensor's recording (livox-viz fit frame.pcd --preset "
                            "livox_tele15 --out twin.json)",
            "livox-viz fit --model track horizon --preset livox_horizon --out mine.json",
            _fit_arguments),
    Command("compare", cmd_compare, "coverage, radial density and track residual of a preset against a table, a "
                                    "recording or another preset",
            "livox-viz compare --preset livox_mid70_fitted mid70 --plot compare.png",
            _compare_arguments),
)
