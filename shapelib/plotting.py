"""Plot helpers for geodesics and the study notebooks (needs matplotlib, imported on first use)."""

from __future__ import annotations

import numpy as np

__all__ = ["plot_trajectories", "plot_metric_panels", "plot_geodesic", "animate_geodesic", "outline", "parse_links",
           "plot_shapes_along", "deformation_grid", "plot_deformation", "plot_mean", "plot_modes", "plot_mean_difference", "plot_scores"]


def plot_trajectories(ax, path, *, init=None, lw: float = 1.0):
    """Draw every landmark's trajectory along a path, as in the paper's Figs. 4 and 6.

    Each landmark's trajectory along ``path`` (a geodesic of eq. 8 of [1]_) as a solid black line,
    the initial path ``init`` (default: the straight line between the ends) dashed grey; start
    landmarks as open circles, end landmarks as filled squares.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    path : array_like, shape (n + 1, K, 2)
        The path.
    init : array_like, shape (n + 1, K, 2), optional
        The initial path (default: the straight line between the ends).
    lw : float, default 1.0
        Line width of the trajectories.

    Returns
    -------
    None

    See Also
    --------
    shapelib.plotting.plot_geodesic : A whole figure of one geodesic.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import plot_trajectories
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> r = sl.geodesic(u, 1.1 * u - 0.05, sigma2=0.5, n_steps=4)
    >>> fig, ax = plt.subplots()
    >>> plot_trajectories(ax, r.path)
    >>> len(ax.lines)
    10
    >>> plt.close(fig)
    """
    _draw_trajectories(ax, np.asarray(path), init=init, lw=lw)
    ax.set_aspect("equal")


def _draw_trajectories(ax, path, *, init=None, lw: float = 1.0):
    """:func:`plot_trajectories` on 2-D or 3-D axes, without the axes' set-up."""
    init = np.linspace(path[0], path[-1], len(path)) if init is None else np.asarray(init)
    for j in range(path.shape[1]):
        ax.plot(*init[:, j].T, "--", color="0.6", lw=0.8)
        ax.plot(*path[:, j].T, "-", color="k", lw=lw)
    ax.plot(*path[0].T, "o", mfc="white", mec="k", ms=5, ls="none", label="start")
    ax.plot(*path[-1].T, "s", color="k", ms=4, ls="none", label="end")


def _trajectory_legend():
    """The legend entries of :func:`plot_geodesic`'s trajectories and ends: ``(handles, labels)``."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="k", lw=1.0), Line2D([], [], ls="--", color="0.6", lw=0.8),
               Line2D([], [], ls="", marker="o", mfc="white", mec="k", ms=5),
               Line2D([], [], ls="", marker="s", color="k", ms=4)]
    return handles, ["landmark trajectory", "straight line (initial path)", "start landmarks", "end landmarks"]


def plot_metric_panels(results: dict, *, figsize=(10, 4.5), lw: float = 1.0):
    """Figs. 4 and 6 layout: (a) Fisher–Rao and (b) α-order trajectories side by side.

    Each panel draws the geodesic of eq. (8) of [1]_ under one metric (eq. 6, eq. 22) over the
    dashed straight-line initialisation. One legend for both panels sits below them, outside the
    axes, so that it never covers a trajectory or a landmark.

    Parameters
    ----------
    results : dict
        ``{"fisher_rao": GeodesicResult, "alpha": GeodesicResult}``.
    figsize : tuple, default (10, 4.5)
        Figure size in inches.
    lw : float, default 1.0
        Line width of the trajectories.

    Returns
    -------
    fig : matplotlib.figure.Figure
        The figure.
    axes : ndarray of matplotlib.axes.Axes
        The two panels.

    See Also
    --------
    shapelib.plotting.plot_trajectories : One panel.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import plot_metric_panels
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> results = {m: sl.geodesic(u, 1.1 * u - 0.05, metric=m, sigma2=0.5, n_steps=4)
    ...            for m in ("fisher_rao", "alpha")}
    >>> fig, axes = plot_metric_panels(results)
    >>> [ax.get_title() for ax in axes]
    ['(a) Fisher–Rao, σ² = 0.5', '(b) α-order entropy, σ² = 0.5']
    >>> plt.close(fig)
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
    """An animation of the shapes along a geodesic, one frame per path point, forth and back.

    A matplotlib :class:`~matplotlib.animation.FuncAnimation` of the shapes along ``result.path``
    (the intrinsic deformation of [1]_, a :class:`~shapelib.GeodesicResult`);
    ``closed`` draws each shape as a closed outline in landmark order, unless ``links`` says which
    landmarks to join. Save it with ``anim.save(path, writer=...)``.

    Parameters
    ----------
    result : GeodesicResult
        The geodesic.
    title : str
        Title (the time ``t`` is appended per frame).
    closed : bool, default True
        Close the outline (when ``links`` is None).
    links : list of (int, int), optional
        Pairs of 0-based landmark indices (:func:`~shapelib.plotting.parse_links`); ``[]``: points
        only.

    Returns
    -------
    matplotlib.animation.FuncAnimation
        The animation (keep a reference until it is saved or shown).

    See Also
    --------
    shapelib.plotting.plot_geodesic : A still figure.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import animate_geodesic
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> anim = animate_geodesic(sl.geodesic(u, 1.1 * u - 0.05, sigma2=0.5, n_steps=4), title="square")
    >>> import os, tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     anim.save(os.path.join(tmp, "square.gif"), writer="pillow", dpi=30)
    ...     os.path.getsize(os.path.join(tmp, "square.gif")) > 0
    True
    >>> plt.close("all")
    """
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

    path = np.asarray(result.path)
    frames = list(range(len(path))) + list(range(len(path) - 2, 0, -1))
    if links is None:
        links = _outline_links(path.shape[1], closed=closed)
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
    """Which landmarks a drawing joins, from text.

    ``"contour"`` (a closed outline in landmark order), or pairs of landmark numbers counted from 1
    as in the file, ``"1-2,2-3,5-1"`` (what geomorph's and Momocs' ``links`` hold). A drawing of the
    landmarks of a shape θ of eq. (9) of [1]_.

    Parameters
    ----------
    text : str
        ``"contour"`` or comma-separated pairs ``"a-b"``.
    n_landmarks : int
        Number of landmarks of the shapes.

    Returns
    -------
    list of (int, int)
        0-based index pairs.

    Raises
    ------
    ValueError
        Naming a malformed pair or a landmark number outside ``1..n_landmarks``, or for no pairs.

    See Also
    --------
    shapelib.plotting.plot_geodesic, shapelib.plotting.animate_geodesic

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> from shapelib.plotting import parse_links
    >>> parse_links("1-2, 2-3", 3)
    [(0, 1), (1, 2)]
    >>> parse_links("contour", 3)
    [(0, 1), (1, 2), (2, 0)]
    """
    text = str(text).strip()
    if text.lower() == "contour":
        return _outline_links(int(n_landmarks), closed=True)
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


def _outline_links(k: int, *, closed: bool) -> list[tuple[int, int]]:
    """The pairs that join ``k`` landmarks in order, the last to the first when ``closed`` (and k > 2)."""
    return [(j, j + 1) for j in range(k - 1)] + ([(k - 1, 0)] if closed and k > 2 else [])


def plot_geodesic(result, *, links=(), title: str = "", long_side: float = 6.0):
    """One geodesic (Figs. 4 and 6 style) in a figure fitted to the shapes.

    Every landmark's trajectory along the geodesic of eq. (8) of [1]_ (solid) over the straight
    line between the ends (dashed), start landmarks as open circles, end landmarks as filled
    squares, and, if ``links`` are given, the start and end shapes drawn by joining those
    landmarks. A legend below the axes; the figure's proportions follow the shapes' extent (a thin
    wing is drawn wide, not lost in a square).

    Parameters
    ----------
    result : GeodesicResult
        The geodesic.
    links : sequence of (int, int)
        0-based landmark pairs (:func:`~shapelib.plotting.parse_links`); empty: none drawn.
    title : str
        The axes' title.
    long_side : float, default 6.0
        Length of the figure's longer side, in inches.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    See Also
    --------
    shapelib.plotting.plot_trajectories : The trajectories alone, on given axes.
    shapelib.geodesic : What it draws.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import parse_links, plot_geodesic
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> r = sl.geodesic(u, 1.1 * u - 0.05, sigma2=0.5, n_steps=4)
    >>> fig = plot_geodesic(r, links=parse_links("contour", 4), title="square")
    >>> fig.axes[0].get_title()
    'square'
    >>> plt.close(fig)
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    path = np.asarray(result.path)
    if path.shape[2] == 3:
        return _plot_geodesic_3d(result, links=links, title=title, long_side=long_side)
    fig, ax = plt.subplots(figsize=_fitted_size(path, long_side=long_side, legend=True), layout="constrained")
    if links:
        _draw_links(ax, path[0], links, ls="--", color="0.55", lw=0.9)
        _draw_links(ax, path[-1], links, ls="-", color="0.55", lw=0.9)
    plot_trajectories(ax, path)
    _fit_axes(ax, path)
    ax.set_title(title)
    handles, labels = _trajectory_legend()
    if links:
        handles += [Line2D([], [], ls="--", color="0.55", lw=0.9), Line2D([], [], ls="-", color="0.55", lw=0.9)]
        labels += ["start shape (links)", "end shape (links)"]
    fig.legend(handles, labels, loc="outside lower center", ncol=min(3, len(labels)), fontsize=8, frameon=False)
    return fig


def _plot_geodesic_3d(result, *, links, title, long_side):
    """:func:`plot_geodesic` for 3-D landmarks: the same trajectories, ends and links on a 3-D axes."""
    import matplotlib.pyplot as plt

    path = np.asarray(result.path)
    fig = plt.figure(figsize=(long_side, long_side), layout="constrained")
    ax = fig.add_subplot(1, 1, 1, projection="3d")
    _draw_trajectories(ax, path)
    _draw_links(ax, path[0], links or (), ls="--", color="0.55", lw=0.9)
    _draw_links(ax, path[-1], links or (), ls="-", color="0.55", lw=0.9)
    _axes_3d_labels(ax)
    ax.set_title(title)
    fig.legend(*_trajectory_legend(), loc="outside lower center", ncol=2, fontsize=8, frameon=False)
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
    """One line per landmark pair of ``links`` (2-D or 3-D); the lines."""
    return [ax.plot(*shape[[a, b]].T, **style)[0] for a, b in links]


def outline(shape, closed: bool = True) -> np.ndarray:
    """The landmarks of ``shape`` in order, the first repeated at the end when ``closed``.

    Parameters
    ----------
    shape : ndarray, shape (K, d)
        Landmarks (the means of eq. 5 of [1]_).
    closed : bool, default True
        Repeat the first landmark at the end.

    Returns
    -------
    ndarray, shape (K + 1, d) or (K, d)
        The outline's vertices.

    See Also
    --------
    shapelib.plotting.plot_shapes_along

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.plotting import outline
    >>> outline(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
    array([[0., 0.],
           [1., 0.],
           [0., 1.],
           [0., 0.]])
    """
    return np.vstack([shape, shape[:1]]) if closed else shape


# ---------------------------------------------------------------------------------------------
# Shapes out: intermediate shapes, deformation grids by the extrinsic warp, modes, group means
# ---------------------------------------------------------------------------------------------


def _draw_shape(ax, shape, *, closed, links=None, label=None, **kw):
    """One shape: the landmarks joined by ``links`` (0-based pairs, :func:`parse_links`) with the
    landmarks as points, or without links an outline through the landmarks in order (``closed``
    True/False), or, with ``closed=None`` (anatomical landmarks with no order), the landmarks alone.
    Returns the artists; the first carries ``label``."""
    shape = np.asarray(shape)
    three = shape.shape[1] == 3
    if links:
        style = {k: v for k, v in kw.items() if k not in ("marker", "ms")}
        out = _draw_links(ax, shape, links, **style)
        pts = ax.plot(*shape.T, ls="none", marker=kw.get("marker") or "o", ms=kw.get("ms", 2.5),
                      color=kw.get("color"))
        out[0].set_label(label)
        return out + pts
    if closed is None:
        kw.update(ls="none", marker=kw.get("marker") or "o", ms=kw.get("ms", 3))
    pts = outline(shape, bool(closed))
    if three:
        return ax.plot(pts[:, 0], pts[:, 1], pts[:, 2], label=label, **kw)
    return ax.plot(pts[:, 0], pts[:, 1], label=label, **kw)


def _shape_axes(ax, d: int, *, ticks: bool = True) -> None:
    """Axes for shapes of dimension ``d``: equal scales in 2-D (no ticks unless ``ticks``), x, y, z
    labels in 3-D."""
    if d == 2:
        ax.set_aspect("equal")
        if not ticks:
            ax.set_xticks([])
            ax.set_yticks([])
    else:
        _axes_3d_labels(ax)


def _draw_ends(ax, start, end, *, closed, links, labels=(None, None)):
    """A geodesic's start (grey, dashed) and its (magnified) end (black, landmarks marked)."""
    _draw_shape(ax, start, closed=closed, links=links, color="0.5", ls="--", lw=1.0, label=labels[0])
    _draw_shape(ax, end, closed=closed, links=links, color="k", lw=1.4, marker="o", ms=2.5, label=labels[1])


def _axes_3d_labels(ax) -> None:
    """x, y, z labels on a 3-D axes (its ticks stay: they are how the eye reads depth)."""
    ax.set_xlabel("x", fontsize=7)
    ax.set_ylabel("y", fontsize=7)
    ax.set_zlabel("z", fontsize=7)
    ax.tick_params(labelsize=6)


def plot_shapes_along(ax, path, *, closed: bool | None = True, cmap: str = "viridis", every: int = 1, lw: float = 1.0,
                      landmarks: bool = True, links=None):
    """The shapes along a path as outlines coloured from start to end.

    A geodesic (eq. 8 of [1]_), a mode of variation: every ``every``-th shape and always the ends,
    coloured by ``cmap``; 3-D shapes need an axes with ``projection="3d"``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    path : array_like, shape (n + 1, K, d)
        The shapes.
    closed : bool or None, default True
        Closed outlines; False: open; None: landmarks only (no order).
    links : array_like of int pairs or "contour", optional
        Pairs of 0-based landmark indices to join (:func:`parse_links`); when given, ``closed`` is
        not used. Default: ``closed`` decides (``None``: points only).
    cmap : str, default "viridis"
        Colour map from start to end.
    every : int, default 1
        Draw every ``every``-th shape (the ends always).
    lw : float, default 1.0
        Line width (the ends drawn 1.6 times thicker).
    landmarks : bool, default True
        Mark the landmarks of the ends.

    Returns
    -------
    matplotlib.axes.Axes
        ``ax``.

    See Also
    --------
    shapelib.plotting.plot_deformation : The same geodesic as a deformed grid.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import plot_shapes_along
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> r = sl.geodesic(u, 1.1 * u - 0.05, sigma2=0.5, n_steps=4)
    >>> fig, ax = plt.subplots()
    >>> len(plot_shapes_along(ax, r.path, every=2).lines)
    3
    >>> plt.close(fig)
    """
    import matplotlib.pyplot as plt

    path = np.asarray(path)
    idx = sorted(set(range(0, len(path), max(1, int(every)))) | {len(path) - 1})
    colours = plt.get_cmap(cmap)(np.linspace(0.0, 1.0, len(idx)))
    for c, i in zip(colours, idx):
        end = i in (0, len(path) - 1)
        _draw_shape(ax, path[i], closed=closed, links=links, color=c, lw=lw * (1.6 if end else 0.8),
                    marker="o" if landmarks and end else None, ms=2.5)
    if path.shape[2] == 2:
        ax.set_aspect("equal")
    return ax


def deformation_grid(result, *, mag: float = 1.0, n_lines: int = 15, margin: float = 0.15, points_per_line: int = 60,
                     lam: float = 1e-3, grid_size: int = 48):
    r"""A regular grid of the ambient plane deformed along a geodesic by the extrinsic warp.

    The grid around the start of the geodesic is moved by the paper's likelihood-preserving flow
    (§III-E of [1]_, :func:`shapelib.extrinsic_warp`), which minimises

    .. math::

        E(u, v) = \int \lambda \left[(\nabla^2 u)^2 + (\nabla^2 v)^2\right]
        + \left(\frac{d \log L}{dt}\right)^2 dx \qquad \text{(eq. 26)}

    on each segment, the geodesic first magnified ``mag`` times
    (:func:`shapelib.solver.logexp.magnify`).

    Parameters
    ----------
    result : GeodesicResult
        A 2-D α or Fisher–Rao geodesic.
    mag : float, default 1.0
        Magnification of the geodesic (as geomorph's ``plotRefToTarget(mag=)``).
    n_lines : int, default 15
        Vertical grid lines (horizontal ones in proportion).
    margin : float, default 0.15
        Margin around the start shape, as a fraction of its extent.
    points_per_line : int, default 60
        Points per grid line.
    lam : float, default 1e-3
        λ of eq. (26).
    grid_size : int, default 48
        Flow grid points per axis.

    Returns
    -------
    grid, warped : ndarray (n_lines_total, points_per_line, 2)
        Grid lines before and after (horizontal lines, then vertical ones).
    end : ndarray (K, 2)
        The end shape of the magnified geodesic.

    Raises
    ------
    ValueError
        For 3-D landmarks, or what :func:`shapelib.extrinsic_warp` raises.

    See Also
    --------
    shapelib.plotting.plot_deformation : Draws it.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import shapelib as sl
    >>> from shapelib.plotting import deformation_grid
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> r = sl.geodesic(u, sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False),
    ...                 sigma2=0.5, n_steps=4)
    >>> grid, warped, end = deformation_grid(r, n_lines=5, grid_size=16)
    >>> grid.shape == warped.shape, end.shape
    (True, (4, 2))
    """
    from .comparison.warp import extrinsic_warp
    from .solver.logexp import magnify

    path = np.asarray(result.path)
    if path.shape[2] != 2:
        raise ValueError("deformation grids are drawn in the plane; these landmarks are 3-D")
    geo = magnify(result, mag)
    lo, hi = path[0].min(axis=0), path[0].max(axis=0)
    pad = margin * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    xs, ys = np.linspace(lo[0], hi[0], n_lines), np.linspace(lo[1], hi[1], max(2, int(n_lines * (hi[1] - lo[1]) /
                                                                                      (hi[0] - lo[0]))))
    s = np.linspace(0.0, 1.0, points_per_line)
    horiz = [np.column_stack([lo[0] + s * (hi[0] - lo[0]), np.full_like(s, y)]) for y in ys]
    vert = [np.column_stack([np.full_like(s, x), lo[1] + s * (hi[1] - lo[1])]) for x in xs]
    grid = np.stack(horiz + vert)
    moved = extrinsic_warp(grid.reshape(-1, 2), geo, lam=lam, grid_size=grid_size)[-1]
    return grid, moved.reshape(grid.shape), geo.path[-1]


def plot_deformation(ax, result, *, mag: float = 1.0, n_lines: int = 15, closed: bool | None = True, lw: float = 0.6,
                     links=None, **grid_kw):
    r"""The deformed grid of a geodesic with its start and (magnified) end shapes.

    The grid of :func:`~shapelib.plotting.deformation_grid` (the extrinsic warp of eq. 26 of [1]_),
    the start shape (grey, dashed) and the magnified end shape (black); ``mag`` as geomorph's
    ``plotRefToTarget(mag=)``. The flow minimises

    .. math::

        E(u, v) = \int \lambda \left[(\nabla^2 u)^2 + (\nabla^2 v)^2\right]
        + \left(\frac{d \log L}{dt}\right)^2 dx.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    result : GeodesicResult
        A 2-D α or Fisher–Rao geodesic.
    mag : float, default 1.0
        Magnification.
    n_lines : int, default 15
        Vertical grid lines.
    closed : bool or None, default True
        How to draw the shapes (None: landmarks only).
    links : array_like of int pairs or "contour", optional
        Pairs of 0-based landmark indices to join (:func:`parse_links`); when given, ``closed`` is
        not used. Default: ``closed`` decides (``None``: points only).
    lw : float, default 0.6
        Line width of the grid.
    **grid_kw
        Further options of :func:`~shapelib.plotting.deformation_grid`.

    Returns
    -------
    grid, warped, end
        What :func:`~shapelib.plotting.deformation_grid` returns.

    See Also
    --------
    shapelib.extrinsic_warp : The warp.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import plot_deformation
    >>> u = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    >>> r = sl.geodesic(u, sl.procrustes_align(u, [[0.0, 0.0], [1.3, 0.0], [1.3, 1.2], [0.0, 1.0]], scaling=False),
    ...                 sigma2=0.5, n_steps=4)
    >>> fig, ax = plt.subplots()
    >>> grid, warped, end = plot_deformation(ax, r, mag=2.0, n_lines=5, grid_size=16)
    >>> len(ax.lines) == len(warped) + 2
    True
    >>> plt.close(fig)
    """
    grid, warped, end = deformation_grid(result, mag=mag, n_lines=n_lines, **grid_kw)
    for line in warped:
        ax.plot(line[:, 0], line[:, 1], "-", color="0.55", lw=lw)
    _draw_ends(ax, result.path[0], end, closed=closed, links=links)
    _shape_axes(ax, 2, ticks=False)
    return grid, warped, end


def plot_mean(shapes, result, *, closed: bool | None = True, links=None, title: str = "", figsize=(5, 5)):
    r"""The Fréchet mean over the shapes it summarises, with the Procrustes mean it started from.

    The Fréchet mean of the metric of eq. (22) or (6) of [1]_,

    .. math::

        \bar\theta = \arg\min_\theta \sum_{i=1}^{N} d(\theta, \theta_i)^2,

    drawn over the shapes (light grey) with its start (dashed); 2-D or 3-D landmarks.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        The shapes.
    result : FrechetMeanResult
        From :func:`shapelib.frechet_mean` (its ``mean`` and ``init``).
    closed : bool or None, default True
        How to draw the shapes (None: landmarks only).
    links : array_like of int pairs or "contour", optional
        Pairs of 0-based landmark indices to join (:func:`parse_links`); when given, ``closed`` is
        not used. Default: ``closed`` decides (``None``: points only).
    title : str
        The axes' title.
    figsize : tuple, default (5, 5)
        Figure size in inches.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    See Also
    --------
    shapelib.frechet_mean : What it draws.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import plot_mean
    >>> rng = np.random.default_rng(0)
    >>> t = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    >>> shapes = sl.pose_align(np.c_[np.cos(t), np.sin(t)] + 0.05 * rng.standard_normal((6, 6, 2)))[0]
    >>> fig = plot_mean(shapes, sl.frechet_mean(shapes, sigma2=0.5), title="mean")
    >>> fig.axes[0].get_title()
    'mean'
    >>> plt.close(fig)
    """
    import matplotlib.pyplot as plt

    d = np.asarray(result.mean).shape[1]
    fig = plt.figure(figsize=figsize)
    ax = fig.add_subplot(1, 1, 1, **({"projection": "3d"} if d == 3 else {}))
    for n, x in enumerate(shapes):
        _draw_shape(ax, x, closed=closed, links=links, color="0.8", lw=0.5, ms=1.5,
                    label=f"specimens ({len(shapes)})" if n == 0 else None)
    _draw_shape(ax, result.init, closed=closed, links=links, color="tab:blue", ls="--", lw=1.0, ms=2,
                label="Procrustes mean (start)")
    _draw_shape(ax, result.mean, closed=closed, links=links, color="k", lw=1.4, marker="o", ms=2.5,
                label="Fréchet mean")
    _shape_axes(ax, d)
    ax.legend(loc="lower center", fontsize=8, frameon=False)
    ax.set_title(title, fontsize=9)
    return fig


def plot_modes(pca, *, components=(0, 1), sd=(-2.0, 0.0, 2.0), closed: bool | None = True, links=None,
               figscale: float = 2.6):
    r"""Shapes along the tangent-PCA modes: one row per component, one column per standard deviation.

    Each mode is the geodesic :math:`\exp_{\bar\theta}(s\, \sqrt{\lambda_j}\, e_j)` from the mean
    along the j-th principal direction of the log maps (metric of eq. 22 or 6 of [1]_), drawn over
    the mean (grey, dashed); the mode's explained variance in the panel title; ``closed=None``
    draws landmarks without an outline.

    Parameters
    ----------
    pca : TangentPCAResult
        From :func:`shapelib.tangent_pca`.
    components : sequence of int, default (0, 1)
        The modes (0-based).
    sd : sequence of float, default (-2, 0, 2)
        Standard deviations along each mode.
    closed : bool or None, default True
        How to draw the shapes.
    links : array_like of int pairs or "contour", optional
        Pairs of 0-based landmark indices to join (:func:`parse_links`); when given, ``closed`` is
        not used. Default: ``closed`` decides (``None``: points only).
    figscale : float, default 2.6
        Inches per panel.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    See Also
    --------
    shapelib.tangent_pca : The modes.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import plot_modes
    >>> rng = np.random.default_rng(0)
    >>> t = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    >>> shapes = sl.pose_align(np.c_[np.cos(t), np.sin(t)] + 0.05 * rng.standard_normal((6, 6, 2)))[0]
    >>> fig = plot_modes(sl.tangent_pca(shapes, sigma2=0.5))
    >>> len(fig.axes)
    6
    >>> plt.close(fig)
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    d = pca.mean.shape[1]
    fig = plt.figure(figsize=(figscale * len(sd), figscale * len(components) + 0.4), layout="constrained")
    sub = {"projection": "3d"} if d == 3 else {}
    for r, j in enumerate(components):
        shapes = pca.mode_shapes.get(j)
        if shapes is None or len(shapes) != len(sd):
            shapes = pca.modes((j,), sd)[j]
        for c, (s, shape) in enumerate(zip(sd, shapes)):
            ax = fig.add_subplot(len(components), len(sd), r * len(sd) + c + 1, **sub)
            _draw_shape(ax, pca.mean, closed=closed, links=links, color="0.6", ls="--", lw=0.8, ms=1.5)
            _draw_shape(ax, shape, closed=closed, links=links, color="k", lw=1.2, marker="o", ms=2)
            _shape_axes(ax, d, ticks=False)
            ax.set_title(f"PC{j + 1} ({100 * pca.explained_variance_ratio[j]:.1f} %), {s:+g} SD", fontsize=8)
    handles = [Line2D([], [], color="0.6", ls="--", lw=0.8, marker="o", ms=1.5),
               Line2D([], [], color="k", lw=1.2, marker="o", ms=2)]
    fig.legend(handles, ["Fréchet mean (reference)", "shape along the mode"], loc="outside lower center", ncol=2,
               fontsize=8, frameon=False)
    return fig


def plot_mean_difference(test, *, mag: float = 3.0, closed: bool | None = True, links=None, every: int = 2,
                         n_lines: int = 15, figsize=(9, 4), **grid_kw):
    """Two panels for a test of a difference in mean shape.

    For a :class:`~shapelib.statistics.group.MeanDifferenceResult`: the shapes along the geodesic
    (eq. 8 of [1]_) between the two groups' Fréchet means, and the extrinsic-warp grid (eq. 26) of
    that geodesic magnified ``mag`` times; the permutation p-value in the title.

    Parameters
    ----------
    test : MeanDifferenceResult
        From :func:`shapelib.mean_difference_test` (with ``group_means=True``).
    mag : float, default 3.0
        Magnification of the geodesic in the grid panel.
    closed : bool or None, default True
        How to draw the shapes.
    links : array_like of int pairs or "contour", optional
        Pairs of 0-based landmark indices to join (:func:`parse_links`); when given, ``closed`` is
        not used. Default: ``closed`` decides (``None``: points only).
    every : int, default 2
        Draw every ``every``-th shape along the geodesic.
    n_lines : int, default 15
        Grid lines.
    figsize : tuple, default (9, 4)
        Figure size in inches.
    **grid_kw
        Further options of :func:`~shapelib.plotting.deformation_grid`.

    Returns
    -------
    matplotlib.figure.Figure
        The figure.

    Raises
    ------
    ValueError
        If the test was run without the group means' geodesic.

    See Also
    --------
    shapelib.mean_difference_test : The test.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> import matplotlib.pyplot as plt
    >>> import shapelib as sl
    >>> from shapelib.plotting import plot_mean_difference
    >>> rng = np.random.default_rng(0)
    >>> t = np.linspace(0, 2 * np.pi, 6, endpoint=False)
    >>> shapes = sl.pose_align(np.c_[np.cos(t), np.sin(t)] + 0.05 * rng.standard_normal((6, 6, 2)))[0]
    >>> test = sl.mean_difference_test(shapes, [0, 0, 0, 1, 1, 1], sigma2=0.5, n_permutations=19, geodesic_steps=4)
    >>> fig = plot_mean_difference(test, mag=1.0, n_lines=5, grid_size=16)
    >>> len(fig.axes)
    2
    >>> plt.close(fig)
    """
    import matplotlib.pyplot as plt

    if test.geodesic is None:
        raise ValueError("the test was run with group_means=False: there is no geodesic between the means")
    a, b = test.labels
    path = np.asarray(test.geodesic.path)
    if path.shape[2] == 3:
        from .solver.logexp import magnify

        fig = plt.figure(figsize=figsize, layout="constrained")
        ax0 = fig.add_subplot(1, 2, 1, projection="3d")
        plot_shapes_along(ax0, path, closed=closed, every=every, links=links)
        ax0.set_title(f"geodesic from the {a} mean to the {b} mean", fontsize=9)
        ax1 = fig.add_subplot(1, 2, 2, projection="3d")
        end = magnify(test.geodesic, mag).path[-1]
        _draw_ends(ax1, path[0], end, closed=closed, links=links,
                   labels=(f"{a} mean", f"{b} mean, difference magnified {mag:g}×"))
        ax1.legend(loc="lower center", fontsize=7, frameon=False)
        for ax in (ax0, ax1):
            _shape_axes(ax, 3)
    else:
        fig, axes = plt.subplots(1, 2, figsize=figsize, layout="constrained")
        plot_shapes_along(axes[0], path, closed=closed, every=every, links=links)
        axes[0].set_title(f"geodesic from the {a} mean to the {b} mean", fontsize=9)
        plot_deformation(axes[1], test.geodesic, mag=mag, n_lines=n_lines, closed=closed, links=links, **grid_kw)
        axes[1].set_title(f"{a} → {b}, magnified {mag:g}×", fontsize=9)
    fig.suptitle(f"{test.pooled.options.metric}: distance {test.distance:.3g}, permutation p = {test.p_value:.3g}",
                 fontsize=10)
    return fig


def plot_scores(scores, groups=None, *, components=(0, 1), hulls: bool = True, labels=None, explained=None,
                ax=None, title: str = ""):
    """A scatter of PC scores (N, ≥ 2) — tangent PCA, Procrustes PCA, MDS — coloured by group, each
    group's convex hull drawn (``hulls``), a legend with the group sizes; ``explained`` (the
    variance ratios) labels the axes with their shares. Returns the figure.

    The scores are typically those of principal components in the tangent space of the metric of
    [1]_, or of Procrustes coordinates [2]_.

    Parameters
    ----------
    scores : array_like, shape (N, p)
        One row of scores per specimen, ``p > max(components)``.
    groups : array_like, shape (N,), optional
        Group of each specimen (default: one group, ``"specimens"``).
    components : (int, int)
        The two columns plotted, 0-based (PC1 and PC2 by default).
    hulls : bool
        Draw each group's convex hull (groups of at least 3 points, not collinear).
    labels : sequence, optional
        A text next to each point.
    explained : array_like, optional
        Variance ratio of each component, shown in the axis labels as a percentage.
    ax : matplotlib.axes.Axes, optional
        Draw there (default: a new figure).
    title : str
        The axes' title.

    Returns
    -------
    matplotlib.figure.Figure
        The figure drawn on.

    See Also
    --------
    shapelib.tangent_pca : Scores in the tangent space of a metric.
    shapelib.statistics.distance_based.classical_mds : Scores from a distance matrix.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.
    .. [2] I. L. Dryden and K. V. Mardia, *Statistical Shape Analysis*, Wiley, 1998.

    Examples
    --------
    >>> import numpy as np, matplotlib
    >>> matplotlib.use("Agg")
    >>> from shapelib.plotting import plot_scores
    >>> rng = np.random.default_rng(0)
    >>> fig = plot_scores(rng.normal(size=(20, 3)), np.repeat(["a", "b"], 10))
    >>> sorted(t.get_text() for t in fig.axes[0].get_legend().get_texts())
    ['a (n = 10)', 'b (n = 10)']
    """
    import matplotlib.pyplot as plt
    from scipy.spatial import ConvexHull, QhullError

    s = np.asarray(scores, dtype=np.float64)
    if s.ndim != 2 or s.shape[1] <= max(components):
        raise ValueError(f"scores must be (N, >{max(components)}) for components {components}; got shape {s.shape}")
    a, b = components
    if ax is None:
        fig, ax = plt.subplots(figsize=(5.5, 4.5), layout="constrained")
    else:
        fig = ax.figure
    g = np.asarray(groups if groups is not None else np.repeat("specimens", len(s)), dtype=object)
    if len(g) != len(s):
        raise ValueError(f"groups has {len(g)} labels for {len(s)} rows of scores")
    levels = sorted(set(g.tolist()), key=str)
    colours = plt.get_cmap("tab10")(np.arange(len(levels)) % 10)
    for colour, level in zip(colours, levels):
        pts = s[g == level][:, [a, b]]
        ax.plot(pts[:, 0], pts[:, 1], "o", ms=4, color=colour, label=f"{level} (n = {len(pts)})", alpha=0.85)
        if hulls and len(pts) >= 3:
            try:
                hull = ConvexHull(pts)
            except QhullError:  # collinear points: no hull to draw
                continue
            ring = np.r_[hull.vertices, hull.vertices[:1]]
            ax.fill(pts[ring, 0], pts[ring, 1], color=colour, alpha=0.12, lw=0)
            ax.plot(pts[ring, 0], pts[ring, 1], "-", color=colour, lw=0.8)
    if labels is not None:
        for (x, y), text in zip(s[:, [a, b]], labels):
            ax.annotate(str(text), (x, y), fontsize=6, xytext=(2, 2), textcoords="offset points")
    share = (lambda j: f" ({100 * explained[j]:.1f} %)") if explained is not None else (lambda j: "")
    ax.set_xlabel(f"PC{a + 1}{share(a)}")
    ax.set_ylabel(f"PC{b + 1}{share(b)}")
    ax.axhline(0, color="0.85", lw=0.6, zorder=0)
    ax.axvline(0, color="0.85", lw=0.6, zorder=0)
    ax.legend(fontsize=8, frameon=False)
    ax.set_title(title, fontsize=9)
    return fig
