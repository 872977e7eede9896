"""Fit time and figures on the measured Mid-40 table (issue: validate against a measured pattern).

Prints the time of a whole fit (shape and structure) of the 4 s table against
the 30 s target, next to the time of merely reading the table in the same run,
and the fitted figures.
"""

from __future__ import annotations

import time

from livox_viz.fitting.compare import compare
from livox_viz.fitting.reference import load_reference
from livox_viz.fitting.rosette_fit import fit_reference


def main() -> None:
    start = time.perf_counter()
    reference = load_reference("mid40")
    read = time.perf_counter() - start
    start = time.perf_counter()
    result = fit_reference(reference)
    fit = time.perf_counter() - start
    shape = result.shape
    print(f"fit of {reference.name} ({reference.seconds:g} s, {len(reference.t):,} points): {fit:.2f} s "
          f"(target <= 30 s); reading the table: {read:.2f} s")
    print(f"  shape residual rms {shape.rms_deg:.4f} deg (target <= 0.25), p95 {shape.p95_deg:.4f} deg")
    table = compare(result.config, reference, seed=0, seconds=(0.1, 0.5, 1.0))
    for t, ref, ours in zip(table.seconds, table.coverage_reference, table.coverage_ours, strict=True):
        print(f"  coverage at {t:g} s: reference {100 * ref:.1f} %, fitted {100 * ours:.1f} % "
              f"({100 * (ours - ref):+.1f} pp, target within 3)")


if __name__ == "__main__":
    main()
