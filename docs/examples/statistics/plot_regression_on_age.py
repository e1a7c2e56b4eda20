"""
Shape against age: geodesic regression
======================================

Geodesic regression fits the geodesic :math:`\\gamma(t) = \\exp_p(t\\, v)` that minimises the
sum of squared distances to the shapes at their ages,

.. math::

   (\\hat p, \\hat v) = \\arg\\min_{p, v} \\sum_{i=1}^{N} d\\big(\\exp_p(t_i v),\\, y_i\\big)^2 ,

and reports Fletcher's :math:`R^2`, the share of the variance about the Fréchet mean that the
trend explains. Here: 12 corpus callosum outlines of the ADHD-200 sample, aged about 7 to 21.
"""

# %%
import matplotlib.pyplot as plt
import numpy as np

import shapelib as sl
from shapelib.datasets import load_adhd200
from shapelib.plotting import plot_shapes_along

raw, clinical = load_adhd200()
rng = np.random.default_rng(1)
pick = np.sort(rng.choice(len(raw), size=12, replace=False))
shapes = sl.to_centroid_size(raw[pick])
age = clinical["age"].to_numpy(dtype=np.float64)[pick]
print(f"{len(age)} shapes, ages {age.min():.1f} to {age.max():.1f}")

reg = sl.geodesic_regression(shapes, age, metric="alpha", sigma2=1.2, n_jobs=1)
print(reg.summary())

# %%
# The fitted trend, from the youngest to the oldest age of the sample (colour: age). On so few
# shapes the trend is small against the spread of the population: ``reg.r2`` says how much of it
# age explains.
ages = np.linspace(age.min(), age.max(), 5)
fig, ax = plt.subplots(figsize=(6, 3))
plot_shapes_along(ax, reg.predict(ages))
ax.set_title(f"predicted shape at ages {ages[0]:.0f} to {ages[-1]:.0f}"
             f" (R² = {reg.r2:.3f})")
plt.show()
