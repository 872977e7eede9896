"""``fit RECORDING``: a head's preset made the twin of a real sensor from one of its recordings.

The recording (a PCD, PLY or CSV frame in firing order with its no-returns, an
LVX2, LVX or a Livox driver's bag) is held against a head's track
(``--preset``, else the head the file names, else the shipped head whose track
explains its first milliseconds best), and
:func:`~livox_viz.fitting.recording_fit.fit_recording` finds its mirror image,
laser order, phases and motor speeds. The report gives the residual per 2 ms
window and against random phases, and the recording's return statistics;
``--out`` writes the head's preset with the recording's track.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from livox_viz.config.presets import DESCRIPTION_KEY, load_preset
from livox_viz.config.sensor import SensorConfig
from livox_viz.core.errors import LivoxVizError
from livox_viz.files.frame_files import FRAME_SUFFIXES, FrameRows, read_frame_rows
from livox_viz.fitting.recording_fit import RecordedFrame, RecordingFit, fit_recording, head_likeness
from livox_viz.fitting.reference import is_point_csv

from .common import UsageError, config_from_args, config_label, write_config_json

#: Livox's device types (LVX files) and the shipped preset of each head.
DEVICE_PRESETS: dict[int, str] = {1: "livox_mid40_risley", 2: "livox_tele15", 3: "livox_horizon",
                                  6: "livox_mid70_risley", 7: "livox_avia", 9: "livox_mid360", 10: "livox_hap"}
#: The heads tried when neither the user nor the file names one.
GUESSED_HEADS: tuple[str, ...] = ("livox_tele15", "livox_horizon", "livox_mid360", "livox_avia", "livox_hap",
                                  "livox_mid40_risley", "livox_mid70_risley")
#: Guessed heads fitted in turn until one explains the recording.
GUESS_TRIES = 3
#: Seconds of a recording fitted by default: one 10 Hz frame.
DEFAULT_FRAME_SECONDS = 0.1


def is_recording(text: str) -> bool:
    """Whether ``fit``'s input is a recorded frame (a CSV only when its header names x, y and z)."""
    suffix = Path(text).suffix.lower()
    return is_point_csv(text) if suffix == ".csv" else suffix in FRAME_SUFFIXES


def _heads(args: argparse.Namespace, rows: FrameRows, frame: RecordedFrame) -> list[tuple[SensorConfig, str]]:
    """The heads to fit, in order: the one given or the file names, else the shipped heads ranked by how well
    their tracks explain the frame's first milliseconds (the best :data:`GUESS_TRIES`)."""
    if getattr(args, "preset", None) or getattr(args, "config", None):
        return [(config_from_args(args), f"{config_label(args)} (given)")]
    if rows.device_type in DEVICE_PRESETS:
        name = DEVICE_PRESETS[rows.device_type]
        return [(load_preset(name), f"{name} (the file's device type {rows.device_type})")]
    likeness = sorted((head_likeness(load_preset(name), frame), name) for name in GUESSED_HEADS)
    ranking = ", ".join(f"{name} {ratio:.2f}" for ratio, name in likeness[:GUESS_TRIES + 1])
    return [(load_preset(name), f"{name} (guessed; coarse distance against typical: {ranking})")
            for _, name in likeness[:GUESS_TRIES]]


def _first_rows(rows: FrameRows, count: int) -> RecordedFrame:
    """The recording's first ``count`` rows as a frame to fit."""
    return RecordedFrame(rows.name, rows.frd[:count], None if rows.times_s is None else rows.times_s[:count],
                         None if rows.lasers is None else rows.lasers[:count])


def _cut(rows: FrameRows, seconds: float, rate: float) -> RecordedFrame:
    """The recording's first ``seconds`` as a frame to fit."""
    if rows.times_s is not None:
        count = int(np.searchsorted(rows.times_s, seconds, side="left"))
    else:
        count = round(seconds * rate)
    return _first_rows(rows, max(1, min(count, rows.points_m.shape[0])))


def fit_recording_command(args: argparse.Namespace) -> int:
    """Run ``fit RECORDING`` (see the module's docstring)."""
    rows = read_frame_rows(args.reference)
    if rows.points_m.shape[0] == 0:
        raise LivoxVizError(f"{args.reference}: holds no rows; allowed: a frame in firing order")
    seconds = args.frame_seconds
    heads = _heads(args, rows, _first_rows(rows, 50_000))
    refusals = []
    for config, head_said in heads:
        frame = _cut(rows, seconds, float(config.point_rate))
        try:
            fit = fit_recording(config, frame, refit_orders=args.refit_terms)
            break
        except LivoxVizError:
            if len(heads) == 1:
                raise
            refusals.append(head_said.split()[0])
    else:
        raise LivoxVizError(f"{rows.name}: none of the likeliest heads ({', '.join(refusals)}) explains it better "
                            "than random phases; allowed: a frame of a Livox head in firing order with its "
                            "no-returns kept as (0, 0, 0), or --preset HEAD to name its head")
    print(_report(rows, frame, config, head_said, fit))
    if args.out:
        description = (f"{head_said.split()[0]} fitted to the recording {rows.name} "
                       f"({rows.source}): {fit.image}, lasers {fit.laser_order}, motors {fit.ppm[0]:+.0f} and "
                       f"{fit.ppm[1]:+.0f} ppm; median {fit.median_deg:.3g} deg per row (random phases "
                       f"{fit.random_median_deg:.3g} deg)")
        what = write_config_json(args.out, fit.config, args.sdk, {DESCRIPTION_KEY: description})
        print(f"wrote {args.out} ({what})")
    return 0


def _report(rows: FrameRows, frame: RecordedFrame, config: SensorConfig, head_said: str, fit: RecordingFit) -> str:
    times = "its own per-point times" if frame.t is not None else f"row i at i / {config.point_rate:,} s"
    lines = [f"{rows.name}: {frame.rows:,} rows ({rows.source}), {fit.no_return_share:.1%} no-returns, "
             f"{fit.returns:,} returns; times: {times}",
             f"  head             {head_said}",
             "  image            " + ("the preset's track itself (not mirrored)" if fit.image == "as printed" else
                                     f"the preset's track {fit.image}"),
             f"  laser order      {fit.laser_order}; its first row is laser {fit.first_laser} of the preset's",
             f"  motor speeds     {fit.ppm[0]:+.0f} ppm and {fit.ppm[1]:+.0f} ppm against nominal (the sensor's "
             "clock against its motors)",
             f"  residual         median {fit.median_deg:.4f} deg; at random phases {fit.random_median_deg:.3g} deg",
             f"  per 2 ms window  median {np.median(fit.window_median_deg):.4f}, max "
             f"{np.max(fit.window_median_deg):.4f} deg; phases re-aligned in each window: median "
             f"{np.nanmedian(fit.window_aligned_deg):.4f}, max {np.nanmax(fit.window_aligned_deg):.4f} deg"]
    if fit.image != "as printed":
        lines.append("  note             the preset written follows the recording. If its points are not in the "
                     "sensor's own frame (a mount applied, a sensor upside down), convert them first")
    cells = [f"{1000 * start:5.0f}:{value:6.3f}" for start, value in zip(fit.window_start_s, fit.window_median_deg,
                                                                           strict=True)]
    lines.append("  windows (ms: median deg)")
    lines += ["    " + " ".join(cells[i:i + 8]) for i in range(0, len(cells), 8)]
    if rows.reflectivity is not None:
        returned = frame.directions.any(axis=1)
        values = rows.reflectivity[:frame.rows][returned]
        counts, edges = np.histogram(values, bins=8, range=(0, 256))
        share = counts / max(values.size, 1)
        lines.append("  reflectivity     " + "  ".join(f"{int(lo)}-{int(hi) - 1}: {p:.0%}"
                                                       for lo, hi, p in zip(edges[:-1], edges[1:], share,
                                                                            strict=True)))
    if fit.refitted:
        held = fit.held_out_window_deg
        lines.append(f"  terms refitted   {fit.refitted} coefficients; held-out 2 ms windows: median "
                     f"{np.median(held):.4f}, p90 {np.percentile(held, 90):.4f}, max {held.max():.4f} deg")
    lines.append(f"  fitted in        {fit.seconds:.1f} s")
    return "\n".join(lines)


def add_recording_arguments(parser: argparse.ArgumentParser) -> None:
    """``fit``'s options for a recording."""
    parser.add_argument("--refit-terms", type=_orders, metavar="M,L",
                        help="with a recording: also fit the coefficients of the track's terms of orders |m| <= M "
                             "and |l| <= L, where the table's model is off the hardware (e.g. 3,5 for a Mid-360); "
                             "learnt on alternate 10 ms, judged on the others (printed as held out)")
    parser.add_argument("--frame-seconds", type=float, default=DEFAULT_FRAME_SECONDS,
                        help=f"with a recording: how much of it to fit, from its start (default "
                             f"{DEFAULT_FRAME_SECONDS:g} s, one frame)")


def _orders(text: str) -> tuple[int, int]:
    parts = text.split(",")
    try:
        orders = tuple(int(part) for part in parts)
    except ValueError:
        orders = ()
    if len(orders) != 2 or not all(0 <= value <= 16 for value in orders):
        raise argparse.ArgumentTypeError(f"{text!r}; allowed: two whole numbers 0 to 16, M,L (e.g. 3,5)")
    return orders


def check_recording_arguments(args: argparse.Namespace) -> None:
    """Refuse what does not go with a recording, before reading it."""
    if not 0.005 <= args.frame_seconds <= 10.0:
        raise UsageError(f"--frame-seconds {args.frame_seconds:g}; allowed: 0.005 to 10 s")
    if args.to is not None:
        raise UsageError("--to fits a preset to another preset's track; a recording goes without --to")
