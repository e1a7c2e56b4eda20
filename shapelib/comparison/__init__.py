"""The comparison distances and deformations of the paper's Table I and §III-E.

* :mod:`shapelib.comparison.splines` — thin-plate and Wendland spline bending energies;
* :mod:`shapelib.comparison.hausdorff` — Hausdorff distance;
* :mod:`shapelib.comparison.diffeomorphism` — landmark diffeomorphisms (eq. 3, Camion–Younes),
  through the same path solver as the information metrics;
* :mod:`shapelib.comparison.warp` — the extrinsic warp of ambient points (§III-E, eqs. 23–26).

(Procrustes alignment and distance live in :mod:`shapelib.geometry.procrustes`.)
"""
