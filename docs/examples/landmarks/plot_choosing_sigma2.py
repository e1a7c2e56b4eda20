"""
Choosing σ²
===========

σ² is the variance of every component of the mixture: a squared length in the units of the
coordinates. The components must overlap their neighbours, so σ should be of the order of the
spacing between neighbouring landmarks. :func:`shapelib.estimate_sigma2` reads σ² off the data
as the scatter of the landmarks about their mean position (eq. 5 read generatively: each
landmark is a draw from its component), and :func:`shapelib.sigma_ratio` measures σ in landmark
spacings.
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

import shapelib as sl
from shapelib.datasets import load_corpus_callosum

shapes, _ = load_corpus_callosum()
x = sl.to_centroid_size(shapes)
est = sl.estimate_sigma2(x)
print(est.summary())

# %%
# The paper's values σ² = 0.1, 0.5 and 1.5 against the landmark spacing at this scale:
for s2 in (0.1, 0.5, 1.5, float(est.sigma2)):
    ratio = sl.sigma_ratio(x[0], sigma2=s2)
    print(f"sigma2 = {s2:.3g}: sigma = {ratio:.2f} landmark spacings")

# %%
# What σ² does to the shape: the density of one outline at the estimate, at the paper's 0.5 and
# at 4. Small, the mixture is a string of separate bumps; large, the outline blurs into one blob.
# Seven outlines of one structure scatter little about their mean, so the estimate here is
# small; :doc:`/guide/scale` discusses the choice, and a sweep over σ² is part of the study.
lo, hi = x[0].min(0) - 3, x[0].max(0) + 3
gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 160), np.linspace(lo[1], hi[1], 80))
grid = np.column_stack([gx.ravel(), gy.ravel()])
fig, axes = plt.subplots(1, 3, figsize=(10, 2.6), layout="constrained")
for ax, s2 in zip(axes, (float(est.sigma2), 0.5, 4.0)):
    density = sl.gmm_density(grid, x[0], sigma2=s2).reshape(gx.shape)
    ax.contourf(gx, gy, density, levels=20, cmap="Greys")
    ax.plot(*x[0].T, ".", color="C1", ms=2)
    ax.set_title(f"σ² = {s2:.2g}")
    ax.set_aspect("equal")
    ax.set_axis_off()
plt.show()
