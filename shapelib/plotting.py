"""Plot helpers for geodesics and the study notebooks (needs matplotlib, imported on first use)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_trajectories", "plot_metric_panels", "plot_geodesic", "animate_geodesic", "outline", "parse_links"]


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


def animate_geodesic(result, *, title="", closed=True, links=None):
    """A matplotlib :class:`~matplotlib.animation.FuncAnimation` of the shapes along ``result.path``
    (a :class:`~shapelib.solver.geodesic.GeodesicResult`), one frame per path point, forth and back;
    ``closed`` draws each shape as a closed outline in landmark order, unless ``links`` (pairs of
    0-based landmark indices, :func:`parse_links`; ``[]``: points only) says which landmarks to join.
    Save it with ``anim.save(path, writer=...)``."""
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    path = np.asarray(result.path)
    frames = list(range(len(path))) + list(range(len(path) - 2, 0, -1))
    if links is None:
        k = path.shape[1]
        links = [(j, j + 1) for j in range(k - 1)] + ([(k - 1, 0)] if closed and k > 2 else [])
    fig, ax = plt.subplots(figsize=_fitted_size(path, long_side=5.0))
    _fit_axes(ax, path)
    _draw_links(ax, path[0], links, ls="--", color="0.7", lw=0.8)
    _draw_links(ax, path[-1], links, ls=":", color="0.7", lw=0.8)
    segs = _draw_links(ax, path[0], links, ls="-", color="k", lw=1.2)
    (dots,) = ax.plot(*path[0].T, "o", color="k", ms=2.5)
    label = ax.set_title(title)

    def draw(f):
        for seg, (a, b) in zip(segs, links):
            seg.set_data(path[f][[a, b], 0], path[f][[a, b], 1])
        dots.set_data(*path[f].T)
        label.set_text(f"{title}  t = {f / (len(path) - 1):.2f}")
        return (dots, *segs)

    return FuncAnimation(fig, draw, frames=frames, blit=False)


def parse_links(text, n_landmarks: int) -> list[tuple[int, int]]:
    """Which landmarks a drawing joins: ``"contour"`` (a closed outline in landmark order), or pairs
    of landmark numbers counted from 1 as in the file, ``"1-2,2-3,5-1"`` (what geomorph's and Momocs'
    ``links`` hold). Returns 0-based index pairs; ``ValueError`` naming a malformed pair or a
    landmark number outside ``1..n_landmarks``."""
    text = str(text).strip()
    if text.lower() == "contour":
        k = int(n_landmarks)
        return [(j, (j + 1) % k) for j in range(k)] if k > 2 else [(0, 1)][: k - 1]
    pairs = []
    for token in filter(None, (t.strip() for t in text.split(","))):
        parts = token.split("-")
        if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
            raise ValueError(f"links: {token!r} is not a pair of landmark numbers like 1-2 (or give 'contour')")
        a, b = (int(p) for p in parts)
        for m in (a, b):
            if not 1 <= m <= n_landmarks:
                raise ValueError(f"links: {token!r} names landmark {m}, but the shapes have landmarks 1 to {n_landmarks}")
        pairs.append((a - 1, b - 1))
    if not pairs:
        raise ValueError("links: no pairs given (e.g. 1-2,2-3, or 'contour')")
    return pairs


def plot_geodesic(result, *, links=(), title: str = "", long_side: float = 6.0):
    """One geodesic (Figs. 4 and 6 style) in a figure fitted to the shapes: every landmark's
    trajectory (solid) over the straight line between the ends (dashed), start landmarks as open
    circles, end landmarks as filled squares, and, if ``links`` are given (0-based pairs,
    :func:`parse_links`), the start and end shapes drawn by joining those landmarks. A legend
    below the axes; the figure's proportions follow the shapes' extent (a thin wing is drawn wide,
    not lost in a square). Returns the figure."""
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    path = np.asarray(result.path)
    fig, ax = plt.subplots(figsize=_fitted_size(path, long_side=long_side, legend=True), layout="constrained")
    if links:
        _draw_links(ax, path[0], links, ls="--", color="0.55", lw=0.9)
        _draw_links(ax, path[-1], links, ls="-", color="0.55", lw=0.9)
    plot_trajectories(ax, path)
    _fit_axes(ax, path)
    ax.set_title(title)
    handles = [Line2D([], [], color="k", lw=1.0), Line2D([], [], ls="--", color="0.6", lw=0.8),
               Line2D([], [], ls="", marker="o", mfc="white", mec="k", ms=5),
               Line2D([], [], ls="", marker="s", color="k", ms=4)]
    labels = ["landmark trajectory", "straight line (initial path)", "start landmarks", "end landmarks"]
    if links:
        handles += [Line2D([], [], ls="--", color="0.55", lw=0.9), Line2D([], [], ls="-", color="0.55", lw=0.9)]
        labels += ["start shape (links)", "end shape (links)"]
    fig.legend(handles, labels, loc="outside lower center", ncol=min(3, len(labels)), fontsize=8, frameon=False)
    return fig


def _fitted_size(path, *, long_side: float, legend: bool = False):
    """Figure size whose proportions follow the x/y extent of the landmarks (within 1:4 and 4:1)."""
    ext = np.ptp(np.asarray(path).reshape(-1, np.asarray(path).shape[-1])[:, :2], axis=0)
    ratio = float(np.clip(ext[0] / ext[1], 0.25, 4.0)) if ext[1] > 0 else 4.0
    w, h = (long_side, long_side / ratio) if ratio >= 1 else (long_side * ratio, long_side)
    return (max(w, 3.0), max(h, 1.5) + (1.0 if legend else 0.0))


def _fit_axes(ax, path):
    """Equal scales on both axes, limits fitted to every landmark of the path with a 5 % margin."""
    pts = np.asarray(path).reshape(-1, np.asarray(path).shape[-1])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * float(np.max(hi - lo) or 1.0)
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal", adjustable="box")


def _draw_links(ax, shape, links, **style):
    return [ax.plot(shape[[a, b], 0], shape[[a, b], 1], **style)[0] for a, b in links]


def outline(shape, closed: bool = True) -> np.ndarray:
    """The landmarks of ``shape`` in order, the first repeated at the end when ``closed``."""
    return np.vstack([shape, shape[:1]]) if closed else shape
