"""Plot helpers for geodesics and the study notebooks (needs matplotlib, imported on first use)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_trajectories", "plot_metric_panels", "animate_geodesic", "outline"]


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


def animate_geodesic(result, *, title="", closed=True):
    """A matplotlib :class:`~matplotlib.animation.FuncAnimation` of the shapes along ``result.path``
    (a :class:`~shapelib.solver.geodesic.GeodesicResult`), one frame per path point, forth and back;
    ``closed`` draws each shape as a closed outline. Save it with ``anim.save(path, writer=...)``."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    path = np.asarray(result.path)
    frames = list(range(len(path))) + list(range(len(path) - 2, 0, -1))
    fig, ax = plt.subplots(figsize=(4.5, 4.5))
    lo, hi = path.min(axis=(0, 1)), path.max(axis=(0, 1))
    pad = 0.05 * float(np.max(hi - lo) or 1.0)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.plot(*outline(path[0], closed).T, "--", color="0.7", lw=0.8)
    ax.plot(*outline(path[-1], closed).T, ":", color="0.7", lw=0.8)
    (line,) = ax.plot([], [], "-o", color="k", ms=2.5, lw=1.2)
    label = ax.set_title(title)

    def draw(f):
        line.set_data(*outline(path[f], closed).T)
        label.set_text(f"{title}  t = {f / (len(path) - 1):.2f}")
        return (line,)

    return FuncAnimation(fig, draw, frames=frames, blit=False)


def outline(shape, closed: bool = True) -> np.ndarray:
    """The landmarks of ``shape`` in order, the first repeated at the end when ``closed``."""
    return np.vstack([shape, shape[:1]]) if closed else shape
