"""The core CLI commands: info, presets, pattern, coverage, and their bad input."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from livox_viz import ScanPattern
from livox_viz.cli import main


def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_info_prints_the_derived_figures(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "info", "--json")
    figures = json.loads(out)
    assert code == 0
    assert figures["point_rate_pts_per_s"] == 100_000
    assert figures["points_per_figure"] == 50_000 and figures["figure_s"] == 0.5
    assert figures["petal_spacing_deg"] == 18 and figures["flower_step_deg"] == pytest.approx(3.6)
    assert figures["max_decode_error_m"] == pytest.approx(600 / 65534)
    code, out, _ = run(capsys, "info")
    assert "100,000 pts/s" in out and "18 deg apart" in out


def test_presets_lists_user_presets(capsys: pytest.CaptureFixture[str], user_presets: Path, seed_json: dict) -> None:
    (user_presets / "mine.json").write_text(json.dumps(seed_json))
    code, out, _ = run(capsys, "presets", "--json")
    names = {p["name"]: p for p in json.loads(out)}
    assert names["livox_mid70"]["shipped"] and not names["mine"]["shipped"]
    code, out, _ = run(capsys, "info", "--preset", "mine")
    assert code == 0


@pytest.mark.parametrize("suffix", [".npz", ".csv"])
def test_pattern_file_matches_the_generator(tmp_path: Path, capsys: pytest.CaptureFixture[str], suffix: str) -> None:
    out = tmp_path / f"p{suffix}"
    code, _, _ = run(capsys, "pattern", "--seconds", "0.03", "--seed", "4", "--out", str(out))
    assert code == 0
    expected = ScanPattern(__import__("livox_viz").load_preset("livox_mid70"), seed=4).take(3000)
    if suffix == ".npz":
        data = np.load(out)
        assert data["xy_deg"].shape == (3000, 2)
        assert np.array_equal(data["xy_deg"], expected.xy_deg)
        assert np.array_equal(data["t"], expected.t)
        assert np.array_equal(data["figure8"], expected.figure8)
    else:
        with open(out) as handle:
            rows = list(csv.reader(handle))
        assert rows[0] == ["x_deg", "y_deg", "t", "frame", "arc", "petal", "figure8", "flower", "figure"]
        values = np.array(rows[1:], dtype=float)
        np.testing.assert_allclose(values[:, :2], expected.xy_deg, rtol=1e-8, atol=1e-8)
        assert np.array_equal(values[:, 6], expected.figure8)


def test_coverage_json(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(capsys, "coverage", "--seconds", "0.1,0.5", "--json")
    table = json.loads(out)["coverage"]
    assert code == 0 and [row["seconds"] for row in table] == [0.1, 0.5]
    assert 0.08 < table[0]["fraction"] < table[1]["fraction"] < 1


def test_coverage_runs_the_integration_times_its_help_names(capsys: pytest.CaptureFixture[str]) -> None:
    """Without --seconds, coverage reports the four times its help text promises (0.1, 0.5, 1 and 2 s), in that
    order: the default list is what a user reads in --help, so a changed entry is a silent change of the table."""
    code, out, _ = run(capsys, "coverage", "--json")
    assert code == 0
    assert [row["seconds"] for row in json.loads(out)["coverage"]] == [0.1, 0.5, 1.0, 2.0]


@pytest.mark.parametrize(("text", "allowed"), [("0", True), ("1", True), ("0.5", True), ("-0.001", False),
                                               ("1.001", False), ("nan", False)])
def test_a_reflectance_is_allowed_from_0_to_1_both_ends_included(text: str, allowed: bool) -> None:
    """--reflectance takes the closed range [0, 1] its message names: 0 is a black surface (no return) and 1 a
    perfect white one, both physical; just outside either end, or NaN, is refused with the range."""
    import argparse

    from livox_viz.cli.common import reflectance_value

    if allowed:
        assert reflectance_value(text) == float(text)
    else:
        with pytest.raises(argparse.ArgumentTypeError, match="a reflectance from 0 to 1"):
            reflectance_value(text)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["info", "--preset", "nope"], "unknown preset 'nope'"),
        (["info", "--config", "/nonexistent.json"], "no such file"),
        (["pattern", "--seconds", "-1", "--out", "x.npz"], "allowed: a finite number > 0"),
        (["pattern", "--seconds", "nan", "--out", "x.npz"], "allowed: a finite number > 0"),
        (["pattern", "--out", "x.txt"], "allowed: .npz, .csv"),
        (["coverage", "--cell-deg", "0"], "allowed: a finite number > 0"),
        # int() takes "1_000", "+1" and other scripts' digits: listen bound port 1000, request went to window 1.
        (["listen", "--port", "1_000", "--seconds", "0.1"], "'1_000' is not a whole number (digits 0-9)"),
        (["listen", "--port", "\u0669\u0669\u0669\u0669", "--seconds", "0.1"], "is not a whole number (digits 0-9)"),
        (["request", "--to", "127.0.0.1", "--window", "+1", "--dry-run"], "'+1' is not a whole number"),
        (["pattern", "--seed", " 7", "--out", "x.npz"], "' 7' is not a whole number"),
        # --seq-id picks a sensor of --config's Config.json: without one it was ignored.
        (["info", "--seq-id", "3"], "--seq-id 3 without --config; allowed: with --config Config.json"),
        (["info", "--preset", "livox_avia", "--seq-id", "-1"], "--seq-id -1 without --config"),
        (["listen", "--seq-id", "3", "--seconds", "0.1"], "--seq-id 3 without --config"),
        # Options the receiver would not use: --shm read shared memory, --shm-dir alone listened on UDP.
        (["listen", "--shm", "--port", "5000", "--seconds", "0.1"], "--port with --shm; allowed: --host and --port "
                                                                    "for UDP, or --shm"),
        (["listen", "--shm", "--host", "127.0.0.1", "--seconds", "0.1"], "--host with --shm; allowed"),
        (["listen", "--shm-dir", ".", "--seconds", "0.1"], "--shm-dir without --shm; allowed: with --shm"),
        (["publish", "--to", "127.0.0.1:9", "--shm-dir", ".", "--seconds", "0.1"], "--shm-dir with --to; allowed: "
                                                                                   "one of them"),
        # --speed was ignored with --unpaced: a run meant at 2x went as fast as possible.
        (["publish", "--to", "127.0.0.1:9", "--seconds", "0.1", "--unpaced", "--speed", "2"],
         "--speed 2 with --unpaced; allowed: one of them"),
        # "HOST:" (HOST:$PORT with PORT unset) was sent to the default port.
        (["request", "--to", "127.0.0.1:", "--dry-run"], "port '' in '127.0.0.1:'; allowed: HOST alone for the "
                                                         "default port, or HOST:PORT"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *argv)
    assert code == 2
    assert message in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_invalid_config_file_exits_2_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], seed_json: dict
) -> None:
    seed_json["DataWidth"] = 0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(seed_json))
    code, _, err = run(capsys, "pattern", "--config", str(bad), "--out", str(tmp_path / "p.npz"))
    assert code == 2 and "DataWidth" in err and "allowed" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.json"]


def test_prepare_compiles_the_stages_asked_and_refuses_others(capsys: pytest.CaptureFixture[str],
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 45: the window's first datasheet use waited 95-128 s for its compiled loops; `livox-viz prepare` (run
    by make venv) compiles them where the install runs."""
    from livox_viz.casting import warm

    warmed: list[str] = []
    monkeypatch.setattr(warm, "warm", lambda stage: warmed.append(stage) or 0.25)
    status, out, _ = run(capsys, "prepare", "datasheet", "ideal")
    assert status == 0 and warmed == ["datasheet", "ideal"]
    assert "prepare: datasheet ... 0.2 s" in out and out.strip().endswith("(numba's cache; prepared again only after "
                                                                            "an update)")
    warmed.clear()
    assert run(capsys, "prepare")[0] == 0 and warmed == list(warm.STAGES)
    warmed.clear()
    status, _, err = run(capsys, "prepare", "risley", "bogus")
    assert status == 2 and warmed == [] and "prepare 'bogus': no such stage; allowed: ideal, risley" in err
