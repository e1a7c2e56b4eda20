"""Plot helpers shared by the study notebooks (imported only by notebooks; needs matplotlib)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_trajectories", "plot_metric_panels"]


def plot_trajectories(ax, path, *, init=None, lw: float = 1.0):
    """Draw every landmark's trajectory along ``path`` (n+1, K, 2) as a solid black line, the
    initial path ``init`` (default: the straight line between the ends) dashed grey, as in the
    paper's Figs. 4 and 6; start landmarks as open circles, end landmarks as filled squares."""
    path = np.asarray(path)
    init = np.linspace(path[0], path[-1], len(path)) if init is None else np.asarray(init)
    for j in range(path.shape[1]):
        ax.plot(init[:, j, 0], init[:, j, 1], "--", color="0.6", lw=0.8)
        ax.plot(path[:, j, 0], path[:, j, 1], "-", color="k", lw=lw)
    ax.plot(path[0, :, 0], path[0, :, 1], "o", mfc="white", mec="k", ms=5, label="start")
    ax.plot(path[-1, :, 0], path[-1, :, 1], "s", color="k", ms=4, label="end")
    ax.set_aspect("equal")


def plot_metric_panels(results: dict, *, figsize=(10, 4.5), lw: float = 1.0):
    """Figs. 4 and 6 layout: (a) Fisher–Rao and (b) α-order trajectories side by side, each over
    the dashed straight-line initialisation. ``results`` maps metric name to GeodesicResult.

    One legend for both panels sits below them, outside the axes, so that it never covers a
    trajectory or a landmark.
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(1, 2, figsize=figsize, layout="constrained")
    for ax, (m, title) in zip(axes, [("fisher_rao", "(a) Fisher–Rao"), ("alpha", "(b) α-order entropy")]):
        plot_trajectories(ax, results[m].path, lw=lw)
        ax.set_title(f"{title}, σ² = {results[m].sigma2}")
    handles, labels = axes[0].get_legend_handles_labels()
    handles = [Line2D([], [], color="k", lw=lw), Line2D([], [], ls="--", color="0.6", lw=0.8), *handles]
    labels = ["geodesic trajectory", "straight-line initialisation", *labels]
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8, frameon=False)
    return fig, axes
