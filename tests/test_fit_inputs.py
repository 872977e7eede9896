"""Issue 15, the fitting inputs: empty, huge and mistimed tables, unbounded compares, noise, absurd coefficients."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from livox_viz import LivoxVizError, load_config
from livox_viz.cli import main
from livox_viz.fitting.reference import MAX_TABLE_ROWS, load_reference
from livox_viz.fitting.risley_fit import fit_risley

PRESETS = Path(__file__).resolve().parent.parent / "presets"


def one_line_error(capsys: pytest.CaptureFixture[str]) -> str:
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    return captured.err


@pytest.mark.parametrize("command", [
    ["fit", "empty.npy"],
    ["fit", "--model", "track", "empty.npy"],
    ["compare", "empty.npy"],
    ["render", "--reference", "empty.npy", "--seconds", "0.05", "--size", "200x150", "--out", "r.png"],
])
def test_a_zero_row_table_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                      capsys: pytest.CaptureFixture[str], command: list[str]) -> None:
    monkeypatch.chdir(tmp_path)
    np.save(tmp_path / "empty.npy", np.zeros((0, 2), dtype=np.float32))
    assert main(command) == 2
    assert "0 rows; allowed: at least" in one_line_error(capsys)


def test_a_table_over_the_size_limit_is_refused_before_it_is_read(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "huge.npy"
    # 20 M rows, written sparsely: the refusal must come from the header, not from reading 160 MB.
    huge = np.lib.format.open_memmap(path, mode="w+", dtype=np.float32, shape=(20_000_000, 2))
    del huge
    tracemalloc.start()
    try:
        assert main(["fit", "--model", "risley", str(path)]) == 2
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    err = one_line_error(capsys)
    assert f"20,000,000 rows; allowed: at most {MAX_TABLE_ROWS:,}" in err
    assert peak < 20 * 2**20


def test_the_risley_fit_holds_no_rows_by_terms_matrix() -> None:
    """Memory grows with the rows, not with rows x terms: 2 M rows fit in a few times the table's own size."""
    from livox_viz.config.presets import load_preset
    from livox_viz.fitting.reference import ReferencePattern
    from livox_viz.patterns.risley import risley_xy

    k = np.arange(2_000_000)
    xy = risley_xy(load_preset("livox_mid40_risley").risley, k / 1e5)
    long = ReferencePattern("long", xy, k / 1e5, 1e5)
    tracemalloc.start()
    try:
        fit = fit_risley(long)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert fit.rms_deg < 1e-4
    # The old (n, J) design matrix alone was 2 M x 20 x 16 bytes = 640 MB; the table is 32 MB.
    assert peak < 12 * xy.nbytes, f"{peak / 2**20:.0f} MiB"


def test_compare_at_one_row_per_second_stays_within_memory(tmp_path: Path) -> None:
    """``compare TABLE --rate 1`` made a table 400 000 s long and allocated 298 GiB; now it compares its first
    minute, in a process limited to 3 GiB of address space."""
    table = np.load(PRESETS / "tables" / "mid40.npy")
    np.save(tmp_path / "t.npy", table)
    code = textwrap.dedent(f"""
        import resource, sys
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))
        from livox_viz.cli import main
        sys.exit(main(["compare", {str(tmp_path / "t.npy")!r}, "--rate", "1"]))
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=240)
    assert "Traceback" not in result.stderr and "MemoryError" not in result.stderr, result.stderr[-2000:]
    assert result.returncode in (0, 2), result.stderr
    if result.returncode == 0:
        assert "its first 60 s compared" in result.stdout


def test_compare_checks_its_plot_path_before_the_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    import livox_viz.cli.fit_commands as fit_commands

    def no_work(*args, **kwargs):
        raise AssertionError("compare ran before its --plot path was checked")

    monkeypatch.setattr(fit_commands, "compare", no_work)
    (tmp_path / "folder.png").mkdir()
    assert main(["compare", "mid40", "--plot", str(tmp_path / "folder.png")]) == 2
    assert "is a folder" in one_line_error(capsys)
    assert main(["compare", "mid40", "--plot", str(tmp_path / "missing" / "c.png")]) == 2
    assert "does not exist" in one_line_error(capsys)


def _livox_csv(path: Path, rate: float, rows: int = 30_000) -> None:
    """The first rows of the Mid-40 table as a Livox CSV whose Time/s column counts at ``rate``."""
    table = np.degrees(np.load(PRESETS / "tables" / "mid40.npy")[:rows].astype(np.float64))
    lines = ["Time/s,Azimuth/deg,Zenith/deg"]
    lines += [f"{k / rate:.9f},{a:.6f},{90 - e:.6f}" for k, (a, e) in enumerate(table)]
    path.write_text("\n".join(lines) + "\n")


def test_a_csv_time_column_sets_the_rate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "fast.csv"
    _livox_csv(path, 200_000.0)
    table = load_reference(path)
    assert table.rate == pytest.approx(200_000.0, rel=1e-6)
    out = tmp_path / "fast.json"
    assert main(["fit", "--model", "risley", str(path), "--out", str(out)]) == 0
    config = load_config(out)
    # The Mid-40's prisms turn at 4664 and 7294 rpm when its rows come 100 000 a second; read at 200 000 they
    # turn twice as fast, and the preset plays at 200 000 points/s.
    assert sorted(abs(v) for v in config.risley.prism_rpm) == pytest.approx([2 * 4664, 2 * 7294], rel=1e-5)
    assert config.point_rate == 200_000
    capsys.readouterr()
    assert main(["fit", "--model", "risley", str(path), "--rate", "100000"]) == 2
    assert "Time/s column says 200,000 rows/s; --rate 100000 contradicts it" in one_line_error(capsys)
    assert main(["fit", "--model", "risley", str(path), "--rate", "200000"]) == 0


def test_a_csv_that_is_not_utf8_names_the_byte_and_line_of_the_first_bad_byte(tmp_path: Path) -> None:
    """The refusal of a Latin-1 CSV points at the first byte UTF-8 cannot read, counted by hand here: after a
    30-byte header line and two 11-byte rows (newlines included), the degree sign 0xB0 that follows "0.2,1.2" on
    the fourth line is byte 30 + 22 + 7 = 59 (from 0)."""
    path = tmp_path / "latin1.csv"
    path.write_bytes(b"Time/s,Azimuth/deg,Zenith/deg\n0.0,1.0,89\n0.1,1.1,89\n0.2,1.2\xb0,89\n")
    with pytest.raises(LivoxVizError, match=r"not UTF-8 text \(byte 59, line 4\)"):
        load_reference(path)


def test_a_csv_whose_time_column_counts_rows_takes_the_rate_given(tmp_path: Path) -> None:
    path = tmp_path / "index.csv"
    _livox_csv(path, 1.0, rows=2000)
    assert load_reference(path).rate == 100_000.0
    assert load_reference(path, rate=50_000.0).rate == 50_000.0


@pytest.mark.parametrize(("where", "value", "message"), [
    ((0, 2, 0), 1e300, "laser 0's terms add up to 1e+300 deg; allowed: at most 180 deg"),
    ((0, 0, 0), 1e-300, "allowed: deflections in [0.001, 45] deg"),
])
def test_absurd_risley_coefficients_are_refused_when_loaded(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                            where: tuple[int, int, int], value: float,
                                                            message: str) -> None:
    data = json.loads((PRESETS / "livox_mid40_risley.json").read_text())
    laser, term, part = where
    data["LivoxVizRisley"]["coefficients_deg"][laser][term] = [value, 0.0] if part == 0 else [0.0, value]
    path = tmp_path / "absurd.json"
    path.write_text(json.dumps(data))
    for command in (["info", "--config", str(path)],
                    ["pattern", "--config", str(path), "--seconds", "0.01", "--out", str(tmp_path / "p.npz")]):
        assert main(command) == 2
        assert message in one_line_error(capsys)
    assert not (tmp_path / "p.npz").exists()


@pytest.mark.parametrize("model", ["track", "risley", "rflysim"])
def test_a_table_that_does_not_move_is_refused_in_words(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                        model: str) -> None:
    """Every row the same direction: not a percentage of a zero spread (it printed a 300-digit one), but why."""
    still = tmp_path / "still.npy"
    np.save(still, np.tile([[0.1, 1.2]], (200_000, 1)))
    out = tmp_path / "fitted.json"
    assert main(["fit", "--model", model, str(still), "--rate", "100000", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "every row points within 0 deg of one direction" in err
    assert "allowed:" in err and len(err) < 300 and not out.exists()


def test_a_csv_in_radians_is_refused_however_long_its_time_column(tmp_path: Path) -> None:
    """The radians check looks at the angles only: 20 s of Time/s (past 2 pi) must not hide radians."""
    table = np.load(PRESETS / "tables" / "mid40.npy")[:30_000].astype(np.float64)
    path = tmp_path / "radians.csv"
    lines = ["Time/s,Azimuth/deg,Zenith/deg"]
    lines += [f"{k / 1500:.9f},{a:.6f},{math.pi / 2 - e:.6f}" for k, (a, e) in enumerate(table)]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(LivoxVizError, match="look like radians"):
        load_reference(path)
