#!/usr/bin/env python3
"""Mutation run over the model package: does a test fail when the code is made wrong?

Two kinds of mutants, each run against a private copy of the tree (the work
tree is never touched):

* The **deliberate bugs** of ``scripts/mutate_bugs.py``: each one names the
  text it breaks, so a change to the code makes it "not applicable" (said
  loudly) instead of passing unnoticed.
* **Sampled sites**: every mutable site of ``livox_viz/`` is found afresh from
  the AST at each run (no line numbers are stored), then ``--sample`` of
  them are drawn with ``--seed``. A site is a comparison, an arithmetic or
  boolean operator, a number, a unary minus, a ``.T`` transpose or a slice
  bound; its mutant swaps the operator, adds one to an integer or the bound,
  doubles a float, or drops the minus or the transpose. Type annotations,
  docstrings, f-strings and ``strict=``/``flush=`` flags are not mutated.

The clean suite runs first under coverage, one context per test (the
subprocesses a test starts included), to learn which tests run each line, on
``--jobs`` pytest-xdist workers as ``make test`` runs it (6.6 minutes on 2
cores); the map is kept in ``build/mutate-map.json`` until a source changes. A mutant then
runs the tests that ran its line, then the rest of their files, stopping at
the first failure (``pytest -x``), within a time limit of a few times the
clean suite's (a mutant that hangs counts as killed). Code run at import
(module constants, default arguments) and the deliberate bugs run the files
that import the module first, then the whole suite. ``tests/test_lint.py`` is
left out: a mutant that only upsets the linter is not a behaviour a test caught.

Survivors judged equivalent (no test could tell them from the original) are
listed, with the reason, in ``scripts/mutate_equivalent.txt`` by file,
mutation and source line; the rate is printed with and without them.

Usage: ``make mutate`` or ``python scripts/mutate.py [--sample N] [--seed S] [--jobs J]``.
"""

from __future__ import annotations

import argparse
import ast
import hashlib
import json
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "scripts"))
from mutate_bugs import DELIBERATE_BUGS  # noqa: E402

#: What a worker's copy of the tree holds (the layout of the repository, so path-based tests hold too).
COPIED = ("livox_viz", "widgets", "presets", "tests", "benchmarks", "scripts", "screenshots", "docs",
          "README.md", "pyproject.toml")
#: Where the installed package names live in a copy (as pyproject.toml's package-dir maps them).
PACKAGE_DIRS = {"livox_viz": "livox_viz", "livox_viz.widgets": "widgets", "livox_viz.shipped_presets": "presets"}
LEFT_OUT_TESTS = ("tests/test_lint.py",)
EQUIVALENT_FILE = ROOT / "scripts" / "mutate_equivalent.txt"
#: Keyword arguments whose constant is not mutated.
NEUTRAL_KEYWORDS = frozenset({"strict", "flush"})

COMPARE_SWAP = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq,
                ast.NotEq: ast.Eq, ast.Is: ast.IsNot, ast.IsNot: ast.Is, ast.In: ast.NotIn, ast.NotIn: ast.In}
BINOP_SWAP = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult, ast.FloorDiv: ast.Div,
              ast.Mod: ast.FloorDiv, ast.Pow: ast.Mult, ast.BitAnd: ast.BitOr, ast.BitOr: ast.BitAnd}
SYMBOL = {ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=", ast.Eq: "==", ast.NotEq: "!=", ast.Is: "is",
          ast.IsNot: "is not", ast.In: "in", ast.NotIn: "not in", ast.Add: "+", ast.Sub: "-", ast.Mult: "*",
          ast.Div: "/", ast.FloorDiv: "//", ast.Mod: "%", ast.Pow: "**", ast.BitAnd: "&", ast.BitOr: "|",
          ast.And: "and", ast.Or: "or"}


# Sites ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Mutant:
    """One change to one file: the source span ``start``..``end`` (line, byte column) becomes ``text``."""

    path: str
    line: int
    description: str
    start: tuple[int, int] = (0, 0)
    end: tuple[int, int] = (0, 0)
    text: str = ""
    #: For a deliberate bug: the exact text it replaces, and its replacement.
    old: str = ""
    new: str = ""
    name: str = ""
    owner: str = ""
    #: First line of the statement holding the site (what coverage records), and whether that
    #: statement runs when the module is imported (module or class level, a default argument).
    statement_line: int = 0
    import_time: bool = True
    #: Inside a function compiled by numba (``# pragma: no cover - compiled``): coverage never sees its
    #: lines run, so the map cannot name the tests that run it.
    compiled: bool = False

    def apply(self, source: str) -> str:
        """The mutated source; raises ValueError if the mutant no longer fits the code."""
        if self.old:
            if source.count(self.old) != 1:
                raise ValueError(f"the text it breaks occurs {source.count(self.old)} times (expected once)")
            return source.replace(self.old, self.new)
        lines = source.encode().splitlines(keepends=True)
        (l0, c0), (l1, c1) = self.start, self.end
        before = b"".join(lines[: l0 - 1]) + lines[l0 - 1][:c0]
        after = lines[l1 - 1][c1:] + b"".join(lines[l1:])
        return (before + self.text.encode() + after).decode()


def _span(node: ast.AST) -> tuple[tuple[int, int], tuple[int, int]]:
    return (node.lineno, node.col_offset), (node.end_lineno, node.end_col_offset)  # type: ignore[attr-defined]


class _SiteFinder(ast.NodeVisitor):
    """Every mutable site of one module, in source order."""

    def __init__(self, path: str, source: str) -> None:
        self.path = path
        self.mutants: list[Mutant] = []
        self._statement = 0
        self._function_depth = 0
        self._source_lines = source.splitlines()
        self._compiled_depth = 0

    def visit(self, node: ast.AST) -> None:
        if not isinstance(node, ast.stmt):
            return super().visit(node)
        outer, self._statement = self._statement, node.lineno
        try:
            return super().visit(node)
        finally:
            self._statement = outer

    def _add(self, node: ast.AST, replacement: ast.AST | str, description: str, parenthesize: bool = True) -> None:
        text = replacement if isinstance(replacement, str) else ast.unparse(replacement)
        start, end = _span(node)
        self.mutants.append(Mutant(self.path, node.lineno, description, start, end,  # type: ignore[attr-defined]
                                   f"({text})" if parenthesize else text, statement_line=self._statement,
                                   import_time=self._function_depth == 0, compiled=self._compiled_depth > 0))

    # What is never mutated: annotations, docstrings, f-strings.
    def visit_FunctionDef(self, node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
        for decorator in node.decorator_list:
            self.visit(decorator)
        arguments = node.args
        for default in [*arguments.defaults, *[d for d in arguments.kw_defaults if d is not None]]:
            self.visit(default)
        header = " ".join(self._source_lines[node.lineno - 1 : node.body[0].lineno - 1] or
                          [self._source_lines[node.lineno - 1]])
        compiled = "pragma: no cover - compiled" in header
        self._function_depth += 1
        self._compiled_depth += compiled
        try:
            self._body(node.body)
        finally:
            self._function_depth -= 1
            self._compiled_depth -= compiled

    visit_AsyncFunctionDef = visit_FunctionDef

    def visit_ClassDef(self, node: ast.ClassDef) -> None:
        for item in [*node.decorator_list, *node.bases, *node.keywords]:
            self.visit(item)
        self._body(node.body)

    def visit_Module(self, node: ast.Module) -> None:
        self._body(node.body)

    def _body(self, body: list[ast.stmt]) -> None:
        start = 1 if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) else 0
        for statement in body[start:]:
            self.visit(statement)

    def visit_AnnAssign(self, node: ast.AnnAssign) -> None:
        if node.value is not None:
            self.visit(node.value)

    def visit_JoinedStr(self, node: ast.JoinedStr) -> None:
        return

    def visit_keyword(self, node: ast.keyword) -> None:
        # zip(strict=True) and print(flush=True) guard against other bugs or pace output: no behaviour to test.
        if node.arg in NEUTRAL_KEYWORDS and isinstance(node.value, ast.Constant):
            return
        self.visit(node.value)

    def visit_ImportFrom(self, node: ast.ImportFrom) -> None:
        return

    # Sites.
    def visit_Compare(self, node: ast.Compare) -> None:
        for index, op in enumerate(node.ops):
            swap = COMPARE_SWAP.get(type(op))
            if swap is None:
                continue
            mutated = ast.Compare(node.left, list(node.ops), list(node.comparators))
            mutated.ops[index] = swap()
            self._add(node, mutated, f"`{SYMBOL[type(op)]}` -> `{SYMBOL[swap]}`")
        self.generic_visit(node)

    def visit_BinOp(self, node: ast.BinOp) -> None:
        kind = type(node.op)
        if kind is ast.MatMult:
            self._add(node, ast.BinOp(node.right, ast.MatMult(), node.left), "swap the operands of `@`")
        elif kind in BINOP_SWAP and not _is_string(node.left):
            swap = BINOP_SWAP[kind]
            self._add(node, ast.BinOp(node.left, swap(), node.right), f"`{SYMBOL[kind]}` -> `{SYMBOL[swap]}`")
        self.visit(node.left)
        self.visit(node.right)

    def visit_Attribute(self, node: ast.Attribute) -> None:
        if node.attr == "T" and isinstance(node.ctx, ast.Load):
            self._add(node, node.value, "drop the transpose `.T`")
        self.generic_visit(node)

    def visit_AugAssign(self, node: ast.AugAssign) -> None:
        kind = type(node.op)
        swap = BINOP_SWAP.get(kind)
        if swap is not None:
            line = ast.AugAssign(node.target, swap(), node.value)
            self._add(node, line, f"`{SYMBOL[kind]}=` -> `{SYMBOL[swap]}=`", parenthesize=False)
        self.visit(node.value)

    def visit_BoolOp(self, node: ast.BoolOp) -> None:
        swap = ast.Or if isinstance(node.op, ast.And) else ast.And
        self._add(node, ast.BoolOp(swap(), node.values), f"`{SYMBOL[type(node.op)]}` -> `{SYMBOL[swap]}`")
        self.generic_visit(node)

    def visit_UnaryOp(self, node: ast.UnaryOp) -> None:
        if isinstance(node.op, ast.USub):
            if _is_number(node.operand):
                value = -node.operand.value  # type: ignore[attr-defined]
                changed = value + 1 if isinstance(value, int) else 2.0 * value
                self._add(node, repr(changed), f"constant {value!r} -> {changed!r}")
                return
            self._add(node, node.operand, "drop the unary minus")
        elif isinstance(node.op, ast.Not):
            self._add(node, node.operand, "drop `not`")
        self.generic_visit(node)

    def visit_Constant(self, node: ast.Constant) -> None:
        value = node.value
        if isinstance(value, bool):
            self._add(node, repr(not value), f"constant {value!r} -> {not value!r}", parenthesize=False)
        elif isinstance(value, int):
            self._add(node, repr(value + 1), f"constant {value!r} -> {value + 1!r}", parenthesize=False)
        elif isinstance(value, float):
            # Doubled, not plus one: 1e6 + 1 or 1e-9 + 1 would tell nothing about a scale or a tolerance.
            changed = 2.0 * value if value else 1.0
            self._add(node, repr(changed), f"constant {value!r} -> {changed!r}", parenthesize=False)

    def visit_Subscript(self, node: ast.Subscript) -> None:
        self.visit(node.value)
        for part in (node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]):
            if isinstance(part, ast.Slice):
                for bound, name in ((part.lower, "lower"), (part.upper, "upper")):
                    if bound is not None:
                        self._add(bound, ast.BinOp(bound, ast.Add(), ast.Constant(1)),
                                  f"slice {name} bound `{ast.unparse(bound)}` -> `{ast.unparse(bound)} + 1`")
                        if not _is_number(bound):
                            self.visit(bound)
                if part.step is not None:
                    self.visit(part.step)
            else:
                self.visit(part)


def _is_number(node: ast.AST) -> bool:
    """A number literal, or a negated one."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
        node = node.operand
    return isinstance(node, ast.Constant) and isinstance(node.value, int | float) and not isinstance(node.value, bool)


def _is_string(node: ast.AST) -> bool:
    return (isinstance(node, ast.Constant) and isinstance(node.value, str | bytes)) or isinstance(node, ast.JoinedStr)


def find_sites(root: Path = ROOT) -> list[Mutant]:
    """Every site of ``livox_viz/``, file by file in path order."""
    mutants: list[Mutant] = []
    for path in sorted((root / "livox_viz").rglob("*.py")):
        relative = str(path.relative_to(root))
        source = path.read_text(encoding="utf-8")
        finder = _SiteFinder(relative, source)
        finder.visit(ast.parse(source))
        mutants.extend(finder.mutants)
    return mutants


# Equivalent mutants ------------------------------------------------------------------------------------
def load_equivalent() -> list[tuple[str, str, str, str]]:
    """``(path, description, source line, reason)`` rows of :data:`EQUIVALENT_FILE` (``|``-separated)."""
    rows = []
    if EQUIVALENT_FILE.exists():
        for line in EQUIVALENT_FILE.read_text(encoding="utf-8").splitlines():
            if line.strip() and not line.startswith("#"):
                path, description, code, reason = (part.strip() for part in line.split(" | ", 3))
                rows.append((path, description, code, reason))
    return rows


#: The sources as the run found them (a report after edits to the work tree still names the mutated lines).
_SOURCES: dict[str, list[str]] = {}


def source_line(mutant: Mutant, root: Path = ROOT) -> str:
    if mutant.path not in _SOURCES:
        _SOURCES[mutant.path] = (root / mutant.path).read_text(encoding="utf-8").splitlines()
    return _SOURCES[mutant.path][mutant.line - 1].strip()


# Running ---------------------------------------------------------------------------------------------------
@dataclass
class Outcome:
    mutant: Mutant
    status: str  # killed, timeout, survived, not applicable, invalid
    by: str = ""
    seconds: float = 0.0
    detail: str = ""
    #: Every test that failed in the stage that killed it (all of them only with ``--count-killers``).
    killers: list[str] = field(default_factory=list)


@dataclass
class Worker:
    """A private copy of the tree whose package imports resolve to it (also in subprocesses)."""

    directory: Path
    env: dict[str, str] = field(default_factory=dict)
    #: Tests left out of every mutant's run (they failed in the clean run).
    deselected: list[str] = field(default_factory=list)

    @classmethod
    def create(cls, parent: Path, index: int) -> Worker:
        directory = parent / f"tree{index}"
        for name in COPIED:
            source = ROOT / name
            if source.is_dir():
                shutil.copytree(source, directory / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
            elif source.exists():
                directory.mkdir(parents=True, exist_ok=True)
                shutil.copy2(source, directory / name)
        boot = directory / "_mutate_boot"
        boot.mkdir()
        mapping = {name: str(directory / folder) for name, folder in PACKAGE_DIRS.items()}
        (boot / "sitecustomize.py").write_text(_BOOT.format(mapping=json.dumps(mapping)))
        (boot / "_mutate_plugin.py").write_text(_PLUGIN)
        (boot / "coveragerc").write_text(_COVERAGERC.format(data=boot / "coverage" / "data",
                                                            model=directory / "livox_viz", gui=directory / "widgets"))
        # NUMBA_BOUNDSCHECK: a mutated index in a compiled loop raises IndexError, as it would in Python, instead of
        # reading whatever lies past the array (a mutant that passes or fails by the memory's luck).
        env = {**os.environ, "PYTHONPATH": str(boot), "PYTHONDONTWRITEBYTECODE": "1", "NUMBA_BOUNDSCHECK": "1"}
        env.pop("COVERAGE_PROCESS_START", None)
        return cls(directory, env)

    def check_imports(self) -> None:
        code = ("import livox_viz, livox_viz.shipped_presets, livox_viz.cli\n"
                "import importlib.util as u\n"
                "print(livox_viz.__file__, livox_viz.shipped_presets.__file__,\n"
                "      u.find_spec('livox_viz.widgets').origin)")
        result = subprocess.run([sys.executable, "-c", code], cwd=self.directory, env=self.env, capture_output=True,
                                text=True, check=True)
        files = result.stdout.split()
        outside = [f for f in files if not f.startswith(str(self.directory))]
        if outside or len(files) != 3:
            raise SystemExit(f"mutate: the copy does not import itself: {files}")

    def pytest(self, arguments: list[str], limit: float, env: dict[str, str] | None = None,
               extra: tuple[str, ...] = ("-x", "--timeout=120")) -> tuple[int | None, str, float]:
        """Run pytest in the copy; returns (exit code or None on time-out, output, seconds)."""
        command = [sys.executable, "-m", "pytest", *extra, "-q", "--no-header", "-p", "no:cacheprovider",
                   *[f"--ignore={t}" for t in LEFT_OUT_TESTS], *arguments]
        started = time.monotonic()
        env = {**(env or self.env), "LIVOX_VIZ_MUTATE_DEFAULT_SIGNALS": "1"}
        process = subprocess.Popen(command, cwd=self.directory, env=env, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, text=True, start_new_session=True)
        RUNNING.add(process)
        try:
            output, _ = process.communicate(timeout=limit)
            return process.returncode, output, time.monotonic() - started
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            output, _ = process.communicate()
            return None, output, time.monotonic() - started
        finally:
            RUNNING.discard(process)
            if process.poll() is None:  # interrupted: its whole group goes with us
                _kill_group(process)

    def coverage_map(self, processes: int = 1) -> tuple[dict[str, dict[int, set[str]]], float, list[str]]:
        """Run the clean suite under coverage, one context per test; returns which tests run each line.

        ``processes`` > 1 runs it under pytest-xdist as ``make test`` does (each worker measured, its
        data combined with the others'): the map is the same, in half the time on 2 cores.

        Returns ``{path: {line: {test id or "" for import time}}}`` (paths relative to the tree,
        test ids without parameters), the run's seconds, and the tests that failed in it (a few
        timing-sensitive tests may, on a loaded machine under coverage: they are then left out of
        every mutant's run, so that they kill nothing). Subprocesses the tests start are measured
        too, in the context of the test that started them.
        """
        import coverage

        boot = self.directory / "_mutate_boot"
        env = {**self.env, "COVERAGE_PROCESS_START": str(boot / "coveragerc")}
        parallel = ("-n", str(processes), "--dist", "loadgroup", "--max-worker-restart=0") if processes > 1 else ()
        code, output, seconds = self.pytest(["-p", "_mutate_plugin", "tests"], 7200, env, extra=parallel)
        failing = _failed_tests(output)
        passed = re.search(r"(\d+) passed", output)
        if code not in (0, 1) or len(failing) > max(3, 0.02 * int(passed.group(1) if passed else 0)):
            log = ROOT / "build" / "mutate-clean.log"
            log.parent.mkdir(parents=True, exist_ok=True)
            log.write_text(output)
            print(output[-3000:])
            raise SystemExit(f"mutate: the suite fails without any mutant (whole output in {log}); fix that first")
        measured = coverage.Coverage(config_file=str(boot / "coveragerc"))
        measured.combine(strict=True)
        data = measured.get_data()
        lines: dict[str, dict[int, set[str]]] = {}
        for filename in data.measured_files():
            relative = str(Path(filename).relative_to(self.directory))
            by_line = lines.setdefault(relative, {})
            for line, contexts in data.contexts_by_lineno(filename).items():
                by_line.setdefault(line, set()).update(c.split("[", 1)[0] for c in contexts)
        return lines, seconds, failing


#: The pytest processes running now (each the leader of its own process group).
RUNNING: set[subprocess.Popen] = set()


def _kill_group(process: subprocess.Popen) -> None:
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    process.wait()


_BOOT = '''"""Written by scripts/mutate.py: the package names resolve to this copy of the tree."""
import importlib.util
import os
import sys

_MAPPING = {mapping}


class _CopyFinder:
    @classmethod
    def find_spec(cls, fullname, path=None, target=None):
        folder = _MAPPING.get(fullname)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(fullname, folder + "/__init__.py",
                                                      submodule_search_locations=[folder])


sys.meta_path.insert(0, _CopyFinder)

# A run started under nohup ignores SIGHUP, one started in the background SIGINT, and children inherit that:
# give the suite the defaults back (once: a test may itself start a child that ignores them).
if os.environ.pop("LIVOX_VIZ_MUTATE_DEFAULT_SIGNALS", ""):
    import signal

    signal.signal(signal.SIGHUP, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.default_int_handler)

if os.environ.get("COVERAGE_PROCESS_START"):
    import coverage

    coverage.process_startup()  # coverage's own .pth may have started it already
    _measuring = coverage.Coverage.current()
    if _measuring is not None:
        _measuring.switch_context(os.environ.get("LIVOX_VIZ_MUTATE_TEST", ""))
'''

_PLUGIN = '''"""Written by scripts/mutate.py: each test runs in its own coverage context (its subprocesses too)."""
import os
import sys
import warnings

import coverage
import pytest


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    measuring = coverage.Coverage.current()
    os.environ["LIVOX_VIZ_MUTATE_TEST"] = item.nodeid
    if measuring is not None:
        if sys.gettrace() is None:  # a test set its own tracer and then None: measure again from here
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                measuring.stop()
                measuring.start()
        measuring.switch_context(item.nodeid)
    yield
    os.environ["LIVOX_VIZ_MUTATE_TEST"] = ""
    if measuring is not None:
        measuring.switch_context("")
'''

_COVERAGERC = """[run]
parallel = True
data_file = {data}
source =
    {model}
    {gui}
"""


def first_tests(module_path: str, root: Path = ROOT) -> list[str]:
    """Test files that import the module: by its name, from its package, or a name ``livox_viz`` re-exports."""
    relative = Path(module_path)
    if relative.parts[0] == "widgets":
        relative = Path("livox_viz") / relative
    dotted = ".".join(relative.with_suffix("").parts).removesuffix(".__init__")
    parent, _, leaf = dotted.rpartition(".")
    exported = set()
    for node in ast.walk(ast.parse((root / "livox_viz" / "__init__.py").read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module == dotted:
            exported |= {alias.asname or alias.name for alias in node.names}
    chosen = []
    for test in sorted((root / "tests").glob("test_*.py")):
        if f"tests/{test.name}" in LEFT_OUT_TESTS:
            continue
        text = test.read_text(encoding="utf-8")
        hit = dotted in text
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.ImportFrom) and node.module is not None:
                names = {alias.name for alias in node.names}
                hit |= (node.module == parent and leaf in names) or (node.module == "livox_viz" and bool(
                    names & exported))
        if hit:
            chosen.append(f"tests/{test.name}")
    return chosen


def test_stages(mutant: Mutant, lines: dict[str, dict[int, set[str]]] | None, root: Path) -> list[list[str]]:
    """Which tests to run for a mutant, in stages, each stopping at its first failure.

    A line run inside a test (not at import) takes the tests that ran it, then the rest of their
    files (a module-scoped fixture runs once, for its first test), then the other files that import
    the module. Import-time code, code compiled by numba (coverage cannot see it run), and the
    deliberate bugs take the files that import the module, then the rest of the suite. A line
    no test runs takes the files that import the module only.
    """
    first = first_tests(mutant.path, root)
    everything = [["tests", *[f"--ignore={t}" for t in first]]]
    if mutant.compiled:  # coverage is blind inside numba's compiled loops: the importers, then the whole suite
        return [first, *everything] if first else everything
    contexts = None if lines is None or mutant.old else lines.get(mutant.path, {}).get(mutant.statement_line)
    if contexts is None:
        if lines is not None and not mutant.old and not mutant.import_time:
            return [first] if first else []
        return [first, *everything] if first else everything
    if mutant.import_time or "" in contexts:
        return [first, *everything] if first else everything
    tests = sorted(contexts)
    files = sorted({t.split("::", 1)[0] for t in tests})
    rest = [f"--deselect={t}" for t in tests]
    # Last, for a survivor only: the other files that import the module (a test may have hidden its
    # lines from coverage, e.g. by setting its own tracer).
    others = [f for f in first if f not in files]
    return [tests, [*files, *rest], *([others] if others else [])]


def _failed_tests(output: str) -> list[str]:
    return [line.split(" - ")[0].split(" ", 1)[1] for line in output.splitlines()
            if line.startswith(("FAILED ", "ERROR "))]


def run_mutant(worker: Worker, mutant: Mutant, limit: float, lines: dict[str, dict[int, set[str]]] | None,
               count_killers: bool = False) -> Outcome:
    target = worker.directory / mutant.path
    original = target.read_text(encoding="utf-8")
    try:
        mutated = mutant.apply(original)
        compile(mutated, str(target), "exec")
    except (ValueError, SyntaxError) as exc:
        return Outcome(mutant, "not applicable" if mutant.old else "invalid", detail=str(exc))
    stages = test_stages(mutant, lines, worker.directory)
    if not stages:
        return Outcome(mutant, "survived", detail="no test runs this line")
    started = time.monotonic()
    target.write_text(mutated, encoding="utf-8")
    try:
        for stage in stages:
            remaining = limit - (time.monotonic() - started)
            extra = ("--timeout=120",) if count_killers else ("-x", "--timeout=120")
            skip = [f"--deselect={t}" for t in worker.deselected]
            code, output, _ = worker.pytest([*stage, *skip], max(remaining, 1.0), extra=extra)
            if code is None:
                return Outcome(mutant, "timeout", "(time limit)", time.monotonic() - started)
            if code not in (0, 5):  # 5: every test of the stage deselected
                killers = _failed_tests(output)
                return Outcome(mutant, "killed", killers[0] if killers else "(see the output)",
                               time.monotonic() - started, killers=killers)
        return Outcome(mutant, "survived", seconds=time.monotonic() - started)
    finally:
        target.write_text(original, encoding="utf-8")


def _bug_mutants() -> list[Mutant]:
    mutants = []
    for bug in DELIBERATE_BUGS:
        source = (ROOT / bug["path"]).read_text(encoding="utf-8")
        at = source.find(bug["old"])
        line = source.count("\n", 0, at) + 1 if at >= 0 else 0
        mutants.append(Mutant(bug["path"], line, bug["name"], old=bug["old"], new=bug["new"], name=bug["name"],
                              owner=bug.get("owner", "")))
    return mutants


def sample_sites(count: int, seed: int, only: str | None, match: str | None = None) -> tuple[list[Mutant], int]:
    sites = find_sites()
    if only:
        sites = [s for s in sites if re.search(only, s.path)]
    if match:
        sites = [s for s in sites if re.search(match, f"{s.path}:{s.line}: {s.description}")]
    chosen = sites if count <= 0 or count >= len(sites) else random.Random(seed).sample(sites, count)
    return sorted(chosen, key=lambda m: (m.path, m.start)), len(sites)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sample", type=int, default=100, help="sampled sites (0: every site); default 100")
    parser.add_argument("--seed", type=int, default=0, help="seed of the sample; default 0")
    parser.add_argument("--jobs", type=int, default=2, help="mutants run at once, each in its own copy; default 2")
    parser.add_argument("--only", help="regular expression: mutate only files whose path matches")
    parser.add_argument("--match", help="regular expression on 'path:line: mutation': only the sites it finds "
                        "(with --sample 0, every one of them), e.g. to check that a new test kills a survivor")
    parser.add_argument("--bugs-only", action="store_true", help="run only the deliberate bugs")
    parser.add_argument("--no-bugs", action="store_true", help="skip the deliberate bugs")
    parser.add_argument("--list", action="store_true", help="list the sampled mutants and stop")
    parser.add_argument("--json", type=Path, help="also write every outcome to this JSON file")
    parser.add_argument("--count-killers", action="store_true",
                        help="run every covering test (no fail-fast) and list mutants only one test kills")
    parser.add_argument("--map-cache", type=Path, default=ROOT / "build" / "mutate-map.json",
                        help="where the line -> tests map is kept between runs (redone when a source changes); "
                        "default build/mutate-map.json")
    args = parser.parse_args(argv)
    # A terminated run unwinds like Ctrl-C: the pytest process groups are killed, the copies removed.
    signal.signal(signal.SIGTERM, lambda number, frame: sys.exit(128 + number))

    bugs = [] if args.no_bugs else _bug_mutants()
    sampled, site_count = ([], 0) if args.bugs_only else sample_sites(args.sample, args.seed, args.only, args.match)
    for mutant in [*bugs, *sampled]:  # read now: the work tree may change while the run goes on
        source_line(mutant)
    if args.list:
        for mutant in [*bugs, *sampled]:
            print(f"{mutant.path}:{mutant.line}: {mutant.description}")
        print(f"{len(sampled)} of {site_count} sites, {len(bugs)} deliberate bugs")
        return 0

    with tempfile.TemporaryDirectory(prefix="livox-viz-mutate-") as scratch:
        os.chmod(scratch, 0o755)  # a test may run the copy as another user (nobody), as the real tree allows
        workers = [Worker.create(Path(scratch), i) for i in range(max(1, args.jobs))]
        workers[0].check_imports()
        print(f"mutate: {len(bugs)} deliberate bugs, {len(sampled)} of {site_count} sites (seed {args.seed}); "
              "the clean suite first, under coverage: which tests run which line", flush=True)
        lines, clean_seconds, failing = cached_coverage_map(workers[0], args.map_cache, max(1, args.jobs))
        if failing:
            print(f"mutate: warning: {len(failing)} tests failed in the clean run and are left out of every mutant's "
                  f"run: {', '.join(failing)}", flush=True)
        for worker in workers:
            worker.deselected = failing
        # A mutant's stages run in one process: its limit scales with the clean suite's time in one process.
        limit = 3 * clean_seconds * max(1, args.jobs) + 60
        print(f"mutate: clean suite {clean_seconds:.0f} s under coverage ({max(1, args.jobs)} processes); time limit "
              f"{limit:.0f} s per mutant", flush=True)

        free = list(workers)
        lock = threading.Lock()
        done = [0]
        total = len(bugs) + len(sampled)

        def run(mutant: Mutant) -> Outcome:
            with lock:
                worker = free.pop()
            try:
                outcome = run_mutant(worker, mutant, limit, lines, args.count_killers)
            finally:
                with lock:
                    free.append(worker)
                    done[0] += 1
            print(f"[{done[0]}/{total}] {outcome.status:>14}  {mutant.path}:{mutant.line}  {mutant.description}"
                  f"{'  <- ' + outcome.by if outcome.by else ''}  ({outcome.seconds:.0f} s)", flush=True)
            return outcome

        pool = ThreadPoolExecutor(len(workers))
        try:
            outcomes = list(pool.map(run, [*bugs, *sampled]))
        except BaseException:
            pool.shutdown(wait=False, cancel_futures=True)
            for process in list(RUNNING):
                _kill_group(process)
            raise
        pool.shutdown()

    return report(outcomes, bugs, args.json)


def tree_digest(root: Path = ROOT) -> str:
    """A hash of every file the map depends on (the model, the GUI, the tests)."""
    digest = hashlib.sha256()
    for folder in ("livox_viz", "widgets", "tests"):
        for path in sorted((root / folder).rglob("*.py")):
            digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def cached_coverage_map(worker: Worker, cache: Path,
                        processes: int = 1) -> tuple[dict[str, dict[int, set[str]]], float, list[str]]:
    digest = tree_digest()
    if cache.exists():
        stored = json.loads(cache.read_text())
        if stored.get("digest") == digest:
            print(f"mutate: line -> tests map from {cache} (the sources have not changed)", flush=True)
            lines = {path: {int(line): set(tests) for line, tests in by_line.items()}
                     for path, by_line in stored["lines"].items()}
            return lines, float(stored["seconds"]), list(stored["failing"])
    lines, seconds, failing = worker.coverage_map(processes)
    cache.parent.mkdir(parents=True, exist_ok=True)
    cache.write_text(json.dumps({"digest": digest, "seconds": seconds, "failing": failing, "lines": {
        path: {str(line): sorted(tests) for line, tests in by_line.items()} for path, by_line in lines.items()}}))
    return lines, seconds, failing


def report(outcomes: list[Outcome], bugs: list[Mutant], json_path: Path | None) -> int:
    bug_outcomes = outcomes[: len(bugs)]
    site_outcomes = outcomes[len(bugs):]
    status = 0
    if bug_outcomes:
        print("\n== deliberate bugs")
        for outcome in bug_outcomes:
            owner = f" [{outcome.mutant.owner}]" if outcome.mutant.owner else ""
            what = outcome.by or outcome.detail
            print(f"  {outcome.status:>14}  {outcome.mutant.name}{owner}{'  <- ' + what if what else ''}")
            if outcome.status not in ("killed", "timeout"):
                status = 1
    if site_outcomes:
        equivalent = load_equivalent()
        survivors = [o for o in site_outcomes if o.status == "survived"]
        invalid = [o for o in site_outcomes if o.status == "invalid"]
        valid = [o for o in site_outcomes if o.status != "invalid"]
        argued = []
        print("\n== survivors (file:line: mutation | code)")
        for outcome in survivors:
            code = source_line(outcome.mutant)
            reason = next((r for p, d, c, r in equivalent
                           if p == outcome.mutant.path and d == outcome.mutant.description and c == code), None)
            if reason is not None:
                argued.append(outcome)
            mark = f"   [equivalent: {reason}]" if reason else (f"   ({outcome.detail})" if outcome.detail else "")
            print(f"  {outcome.mutant.path}:{outcome.mutant.line}: {outcome.mutant.description} | {code}{mark}")
        killed = sum(o.status in ("killed", "timeout") for o in valid)
        timeouts = sum(o.status == "timeout" for o in valid)
        rate = len(survivors) / len(valid) if valid else 0.0
        real = len(survivors) - len(argued)
        rate_real = real / (len(valid) - len(argued)) if len(valid) > len(argued) else 0.0
        print(f"\n== sampled sites: {len(valid)} mutants, {killed} killed ({timeouts} by time-out), "
              f"{len(survivors)} survived: survival rate {100 * rate:.1f} %")
        print(f"   without the {len(argued)} argued equivalent (scripts/mutate_equivalent.txt): "
              f"{real} of {len(valid) - len(argued)}, {100 * rate_real:.1f} %")
        if invalid:
            print(f"   ({len(invalid)} mutants did not compile and were left out)")
    single = [o for o in outcomes if o.status == "killed" and len(o.killers) == 1]
    if single and any(len(o.killers) > 1 for o in outcomes):
        print(f"\n== killed by exactly one test ({len(single)})")
        for outcome in single:
            print(f"  {outcome.mutant.path}:{outcome.mutant.line}: {outcome.mutant.description}  <- {outcome.by}")
    if json_path is not None:
        json_path.write_text(json.dumps([{"path": o.mutant.path, "line": o.mutant.line,
                                          "mutation": o.mutant.description, "status": o.status, "by": o.by,
                                          "killers": o.killers, "detail": o.detail,
                                          "seconds": round(o.seconds, 1)} for o in outcomes], indent=1))
    return status


if __name__ == "__main__":
    sys.exit(main())
