"""A comparison drawn as a PNG (matplotlib, Agg): both curves and their difference.
"""

from __future__ import annotations

from livox_viz.fitting.compare import Comparison


def plot_comparison(result: Comparison, path, title: str) -> None:
    """Write the comparison as a PNG (matplotlib, Agg): both curves and their difference."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from livox_viz.core.atomic import atomic_path

    figure, axes = plt.subplots(2, 2, figsize=(11, 7), sharex="col", gridspec_kw={"height_ratios": [3, 1]})
    t = result.seconds
    axes[0, 0].plot(t, 100 * result.coverage_reference, "o-", label="reference", color="#1f77b4")
    axes[0, 0].plot(t, 100 * result.coverage_ours, "s--", label="ours", color="#d62728")
    axes[0, 0].set_xscale("log")
    axes[0, 0].set_ylabel("FOV coverage, % (5 mrad cells)")
    axes[0, 0].legend()
    axes[0, 0].grid(True, which="both", alpha=0.3)
    axes[1, 0].plot(t, 100 * (result.coverage_ours - result.coverage_reference), "k.-")
    axes[1, 0].axhline(0, color="grey", lw=0.8)
    axes[1, 0].set_xlabel("integration time, s")
    axes[1, 0].set_ylabel("ours - ref, pp")
    centres = 0.5 * (result.density_edges_deg[1:] + result.density_edges_deg[:-1])
    axes[0, 1].plot(centres, result.density_reference / 1e6, "o-", label="reference", color="#1f77b4")
    axes[0, 1].plot(centres, result.density_ours / 1e6, "s--", label="ours", color="#d62728")
    axes[0, 1].set_ylabel("density, million points / sr / s")
    axes[0, 1].set_yscale("log")
    axes[0, 1].legend()
    axes[0, 1].grid(True, which="both", alpha=0.3)
    axes[1, 1].plot(centres, (result.density_ours - result.density_reference) / 1e6, "k.-")
    axes[1, 1].axhline(0, color="grey", lw=0.8)
    axes[1, 1].set_xlabel(result.profile_label)
    axes[1, 1].set_ylabel("ours - ref")
    figure.suptitle(title)
    figure.tight_layout()
    with atomic_path(path) as tmp:
        figure.savefig(tmp, format="png", dpi=100)
    plt.close(figure)
