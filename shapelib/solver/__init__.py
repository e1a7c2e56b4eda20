"""Paths between shapes: geodesics (eqs. 8–12) and certified distance brackets.

* :mod:`shapelib.solver.geodesic` — the discrete path energy of any metric written as a quadratic
  form on landmark velocities, its damped Newton (Levenberg–Marquardt) minimisation, shooting;
* :mod:`shapelib.solver.bracket` — ``lower ≤ d ≤ upper`` to a requested relative width.

Built on :mod:`shapelib.geometry` only.
"""
