"""The figure of the README and of the documentation's front page: ``docs/_static/geodesic.png``.

A fish outline deforming into a heart along the α-order geodesic: each panel is the shape's
Gaussian-mixture density (eq. 5) at one time of the geodesic, with its landmarks. The outlines
are MPEG-7 silhouettes (``fish-1``, ``Heart-1``; fetched like every dataset of the study, or read
from ``SHAPELIB_DATA_DIR``), 32 landmarks each, aligned by generalized Procrustes at centroid
size 20 (the study's scale, where σ² = 0.5 is about a landmark spacing).

    python docs/_scripts/readme_figure.py [--out docs/_static/geodesic.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import shapelib as sl  # noqa: E402
from shapelib.datasets import mpeg7_landmarks  # noqa: E402

OUT = Path(__file__).resolve().parents[1] / "_static" / "geodesic.png"
SIGMA2 = 0.5
TIMES = 5


def main(argv=None) -> Path:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    shapes = np.stack([mpeg7_landmarks(name, 32) for name in ("fish-1", "Heart-1")])
    u, v = sl.to_centroid_size(shapes, 20.0)  # generalized Procrustes, then centroid size 20
    r = sl.geodesic(u, v, metric="alpha", sigma2=SIGMA2, n_steps=16)
    steps = np.linspace(0, len(r.path) - 1, TIMES).round().astype(int)
    lo, hi = r.path.reshape(-1, 2).min(0) - 2.5, r.path.reshape(-1, 2).max(0) + 2.5
    xs, ys = np.linspace(lo[0], hi[0], 160), np.linspace(lo[1], hi[1], 160)
    grid = np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2)
    fig, axes = plt.subplots(1, TIMES, figsize=(2.0 * TIMES, 2.0), layout="constrained")
    for ax, k in zip(axes, steps):
        density = sl.gmm_density(grid, r.path[k], sigma2=SIGMA2).reshape(len(ys), len(xs))
        ax.imshow(density, origin="lower", extent=(lo[0], hi[0], lo[1], hi[1]), cmap="magma")
        ax.plot(r.path[k, :, 0], r.path[k, :, 1], ".", color="white", ms=2.5)
        ax.set_title(f"t = {k / (len(r.path) - 1):.2g}", fontsize=9)
        ax.set_axis_off()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=80)
    print(f"wrote {args.out} ({args.out.stat().st_size / 1024:.0f} KiB); {r.summary()}")
    return args.out


if __name__ == "__main__":
    main()
