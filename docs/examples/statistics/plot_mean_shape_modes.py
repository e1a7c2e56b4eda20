"""
A mean shape, its modes and a deformation grid
==============================================

The Fréchet mean of shapes :math:`y_1, \\dots, y_N` under the α-order metric minimises the sum
of squared geodesic distances,

.. math::

   \\bar y = \\arg\\min_m \\sum_{i=1}^{N} d_\\alpha(m, y_i)^2 ,

and tangent PCA diagonalises the log maps :math:`\\log_{\\bar y} y_i` in the metric at the
mean, so its modes are orthonormal where the distances are measured. Here: the seven corpus
callosum outlines of the paper's study (63 landmarks each).
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

import shapelib as sl
from shapelib.datasets import load_corpus_callosum
from shapelib.plotting import plot_deformation, plot_mean, plot_modes

raw, _ = load_corpus_callosum()
shapes = sl.to_centroid_size(raw)  # aligned, at the study's scale (centroid size 20)

# n_jobs=1: in this process
mean = sl.frechet_mean(shapes, metric="alpha", sigma2=0.5, n_jobs=1)
print(mean.summary())

# %%
# The mean (black) over the shapes (grey), with the Procrustes mean it started from (dashed).
fig = plot_mean(shapes, mean, title="Fréchet mean of 7 outlines (α, σ² = 0.5)")
plt.show()

# %%
# Tangent PCA at that mean reuses its log maps: no further geodesic is solved.
pca = sl.tangent_pca(shapes, mean=mean, n_jobs=1, modes=(0, 1), sd=(-1.0, 0.0, 1.0))
print("explained variance ratio of the first modes:",
      np.round(pca.explained_variance_ratio[:3], 3))
fig = plot_modes(pca, components=(0, 1), sd=(-1.0, 0.0, 1.0))
plt.show()

# %%
# The first mode as a deformation of the plane: the geodesic from the mean to the shape one
# standard deviation along the mode, magnified 1.5 times (as geomorph's ``plotRefToTarget(mag=)``),
# and a grid carried along it by the paper's extrinsic warp (§III-E). Landmarks slide along a
# dense outline at almost no cost, so a strong magnification tangles the outline before it shows
# more of the shape change.
g = sl.geodesic(mean.mean, pca.mode_shapes[0][-1], metric="alpha", sigma2=0.5,
                n_steps=4)
fig, ax = plt.subplots(figsize=(6, 3.5))
plot_deformation(ax, g, mag=1.5, n_lines=12, points_per_line=30, grid_size=24)
ax.set_title("first mode, +1 SD, magnified 1.5 times")
plt.show()
