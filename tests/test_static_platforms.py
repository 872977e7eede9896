"""The static check for Windows and macOS: nothing the package names is missing there.

There is no Windows machine here. mypy with ``--platform win32`` (and ``darwin``) reads typeshed's
platform-conditional stubs, which leave out what a platform lacks: ``signal.SIGHUP``,
``os.register_at_fork``, ``os.statvfs``, ``os.geteuid``, ``os.pwrite``, everything in ``fcntl`` and
``resource``. A finding of those runs that the ``--platform linux`` run of the same files does not have is
something Windows or macOS lacks; there must be none. (The other findings of a plain ``mypy`` are type
questions that do not depend on the platform.) The files checked are ``[tool.mypy] files`` in pyproject.toml.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FINDING = re.compile(r"^(?P<path>[^:\n]+):(?P<line>\d+): error: (?P<message>.*)$", re.MULTILINE)
PLATFORMS = ("linux", "win32", "darwin")
#: Both tests keep mypy's caches in the same folders: they run on one test process, one after the other.
pytestmark = pytest.mark.xdist_group("mypy-cache")


def _mypy(platform: str, *paths: str, cwd: Path = ROOT) -> subprocess.Popen[str]:
    """mypy for ``platform`` (the pyproject's files when no path is given), its cache kept per platform."""
    cache = ROOT / ".mypy_cache" / platform
    return subprocess.Popen([sys.executable, "-m", "mypy", "--platform", platform, "--cache-dir", str(cache),
                             "--no-error-summary", "--show-error-codes", *paths],
                            cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _findings(process: subprocess.Popen[str]) -> set[tuple[str, int, str]]:
    out, err = process.communicate(timeout=900)
    # 0: no finding, 1: findings; anything else (2: mypy itself failed, a bad option) must not pass unseen.
    assert process.returncode in (0, 1), f"mypy failed: {err or out}"
    return {(m["path"], int(m["line"]), m["message"]) for m in FINDING.finditer(out)}


def platform_findings(*paths: str, cwd: Path = ROOT) -> dict[str, list[str]]:
    """Per platform other than Linux, the findings only that platform has (``path:line: message``)."""
    runs = {platform: _mypy(platform, *paths, cwd=cwd) for platform in PLATFORMS}  # side by side: two cores
    found = {platform: _findings(process) for platform, process in runs.items()}
    return {platform: sorted(f"{path}:{line}: {message}" for path, line, message in found[platform] - found["linux"])
            for platform in PLATFORMS[1:]}


def test_the_check_finds_what_windows_lacks(tmp_path: Path) -> None:
    """The check can fail: each POSIX-only name of the issue is a Windows finding, SIGHUP and fork hooks are not
    macOS ones, and the same names looked up the portable way are none."""
    (tmp_path / "posix_only.py").write_text(
        "import fcntl\nimport os\nimport resource\nimport signal\n\n"
        "HANG_UP = signal.SIGHUP\n"
        "os.register_at_fork(after_in_child=print)\n"
        "fcntl.flock(0, fcntl.LOCK_EX)\n"
        "LIMIT = resource.getrlimit(resource.RLIMIT_NOFILE)\n"
        "PORTABLE = getattr(signal, 'SIGHUP', None), getattr(os, 'register_at_fork', None)\n")
    found = platform_findings("posix_only.py", cwd=tmp_path)
    lines = sorted({int(text.split(":")[1]) for text in found["win32"]})
    assert lines == [6, 7, 8, 9], found
    assert found["darwin"] == [], found


@pytest.mark.timeout(300)
def test_no_platform_findings_for_windows_and_macos() -> None:
    found = platform_findings()
    assert found == {"win32": [], "darwin": []}, found
