"""The geometry of GMM shapes: where each of the paper's equations lives.

* eq. (5), the shape density and its closed-form L² quantities: :mod:`shapelib.geometry.gmm`
* eq. (6) Fisher–Rao and eq. (22) α-order metric tensors and quadratic forms:
  :mod:`shapelib.geometry.metrics` (their compiled kernels: :mod:`shapelib.geometry._kernels`;
  the Fisher–Rao integrals' grid: :mod:`shapelib.geometry.quadrature`)
* pose and size (Procrustes alignment, centroid size): :mod:`shapelib.geometry.procrustes`
* σ against the landmarks' spacing: :mod:`shapelib.geometry.scale`
* the closed-form lower bounds of a whole population as matrix products, and σ² sweeps:
  :mod:`shapelib.geometry.bound_matrices`

Nothing here imports the solver, the engine, IO or plotting.
"""
