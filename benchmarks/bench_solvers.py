#!/usr/bin/env python
"""Why a certified geodesic takes hundreds of iterations: second-order methods compared.

Issue "core", section Speed, asks for a converged α geodesic (relative energy change < 1e-9)
in under a second on the corpus callosum pair (paper shapes 1 and 2; K = 63, σ² = 0.5,
n_steps = 16). One iteration of the library's solver costs ~90 ms, so that needs about ten
iterations; it takes ~200. This script measures whether another second-order method does
better on the same problem. Every method minimises the same piecewise-linear path energy
(:func:`shapelib.solver.geodesic._energy`, exact Hessian of the α metric) from the same straight-line
start and stops on the same certificate as the library: the exact Hessian is positive
definite and the Newton decrement ``½ gᵀH⁻¹g`` is below ``tol · E``.

* ``lm`` — the library: Levenberg–Marquardt on the block-tridiagonal exact Hessian.
* ``coarse_to_fine`` — the library at n = 2, 4, 8, 16, each level started from the previous
  one refined at the segment midpoints (``geodesic(..., init=...)``).
* ``trust_exact`` — SciPy's trust-region method with exact subproblem solves (Moré–Sorensen,
  hard case handled), given our energy, gradient and dense Hessian.
* ``saddle_free`` — Newton with the Hessian's eigenvalues replaced by their absolute values
  (floored at 1e-12 of the largest) and a backtracking line search: moves *down* negative
  curvature instead of damping it away.
* ``polynomial`` — not the library's discretisation: each landmark moves on a polynomial of
  degree ``m`` in time (Lagrange basis on Chebyshev–Lobatto times, Gauss–Legendre in time),
  the same LM loop on the dense exact Hessian. Far fewer unknowns and a smaller energy
  (closer to the squared geodesic distance) than the piecewise-linear path, but not fewer
  iterations.

    python benchmarks/bench_solvers.py [--methods lm trust_exact ...] [--max-iter 300] [--json out.json]

Not a test (minutes; numbers depend on the machine). ``--quick`` runs every method for a few
iterations on n_steps = 4, which ``tests/test_benchmarks.py`` uses to keep the script working.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from shapelib.datasets import load_corpus_callosum  # noqa: E402
from shapelib import to_centroid_size  # noqa: E402

G = importlib.import_module("shapelib.solver.geodesic")  # the module (the package exports the function)
from shapelib.solver.energy import path_energy  # noqa: E402
from shapelib.solver.linalg import block_tridiagonal_dense, one_blas_thread  # noqa: E402
from shapelib.solver.path_metric import AlphaPathMetric  # noqa: E402

METHODS = ("lm", "coarse_to_fine", "trust_exact", "saddle_free", "polynomial")


dense_hessian = block_tridiagonal_dense  # the block-tridiagonal Hessian (diag, upper) as a dense matrix


def newton_decrement(h, g):
    """``½ gᵀH⁻¹g`` if the dense Hessian is positive definite, else None."""
    try:
        return 0.5 * float(g @ cho_solve(cho_factor(h), g))
    except np.linalg.LinAlgError:
        return None


def straight_line(u, v, n):
    t = np.linspace(0.0, 1.0, n + 1)[:, None, None]
    return (1 - t) * u + t * v


def refine(path):
    out = np.empty((2 * len(path) - 1,) + path.shape[1:])
    out[0::2] = path
    out[1::2] = 0.5 * (path[:-1] + path[1:])
    return out


class PathProblem:
    """Energy, gradient, dense Hessian and certificate of the interior path points (flat vector)."""

    def __init__(self, model, u, v, n):
        self.model, self.path0, self.n = model, straight_line(u, v, n), n
        self.shape = self.path0[1:-1].shape
        self._key, self._val = None, None

    def path(self, x):
        p = self.path0.copy()
        p[1:-1] = x.reshape(self.shape)
        return p

    def _eval(self, x):
        key = x.tobytes()
        if key != self._key:
            e, g, blocks = path_energy(self.model, self.path(x), hessian="exact")
            self._key, self._val = key, (e, g.ravel(), dense_hessian(*blocks))
        return self._val

    def energy(self, x):
        return path_energy(self.model, self.path(x), gradient=False)[0]

    def grad(self, x):
        return self._eval(x)[1]

    def hess(self, x):
        return self._eval(x)[2]

    def certified(self, x, tol):
        e, g, h = self._eval(x)
        dec = newton_decrement(h, g)
        return dec is not None and dec < tol * e


def run_lm(u, v, s2, n, tol, max_iter):
    r = G.geodesic(u, v, metric="alpha", sigma2=s2, n_steps=n, tol=tol, max_iter=max_iter, warn=False)
    return {"iterations": r.n_iter, "energy": r.energy, "certified": r.log["stopped_by"] == "newton_decrement"}


def run_coarse_to_fine(u, v, s2, n, tol, max_iter):
    levels = [2 ** j for j in range(1, int(np.log2(n)) + 1)] if n >= 2 else [n]
    path, per_level, r = None, [], None
    for m in levels:
        r = G.geodesic(u, v, metric="alpha", sigma2=s2, n_steps=m, tol=tol, max_iter=max_iter, warn=False,
                       init=None if path is None else refine(path))
        path = r.path
        per_level.append({"n_steps": m, "iterations": r.n_iter, "energy": r.energy})
    return {"iterations": sum(lv["iterations"] for lv in per_level), "energy": r.energy,
            "certified": r.log["stopped_by"] == "newton_decrement", "levels": per_level}


def run_trust_exact(u, v, s2, n, tol, max_iter):
    prob = PathProblem(AlphaPathMetric(s2), u, v, n)
    x0 = prob.path0[1:-1].ravel()
    state = {"it": 0, "certified": False, "x": x0}

    def callback(xk, *args):
        state["it"], state["x"] = state["it"] + 1, np.array(xk)
        if prob.certified(xk, tol):
            state["certified"] = True
            raise StopIteration

    try:
        res = minimize(prob.energy, x0, jac=prob.grad, hess=prob.hess, method="trust-exact", callback=callback,
                       options={"maxiter": max_iter, "gtol": 1e-300})
        x = res.x
    except StopIteration:  # SciPy < 1.11 lets the exception through
        x = state["x"]
    return {"iterations": state["it"], "energy": prob.energy(x), "certified": state["certified"]}


def run_saddle_free(u, v, s2, n, tol, max_iter, floor=1e-12):
    prob = PathProblem(AlphaPathMetric(s2), u, v, n)
    x = prob.path0[1:-1].ravel()
    it, certified = 0, False
    while it < max_iter:
        e, g, h = prob._eval(x)
        w, vec = np.linalg.eigh(h)
        if w[0] > 0 and 0.5 * float(np.sum((vec.T @ g) ** 2 / w)) < tol * e:
            certified = True
            break
        it += 1
        step = -vec @ ((vec.T @ g) / np.maximum(np.abs(w), floor * w[-1]))
        a = 1.0
        for _ in range(50):
            if prob.energy(x + a * step) < e:
                break
            a *= 0.5
        else:
            break  # no decrease along the step at machine precision
        x = x + a * step
    return {"iterations": it, "energy": prob.energy(x), "certified": certified}


def polynomial_basis(m, nq):
    """Lagrange basis of degree ``m`` on Chebyshev–Lobatto times and its derivative, at ``nq``
    Gauss–Legendre nodes of [0, 1]: ``(Phi, dPhi, weights)``."""
    leg = np.polynomial.legendre
    s = 0.5 * (1 - np.cos(np.pi * np.arange(m + 1) / m))
    x, w = leg.leggauss(nq)
    inv = np.linalg.inv(leg.legvander(2 * s - 1, m))
    phi = leg.legvander(x, m) @ inv
    dphi = np.stack([2 * leg.legval(x, leg.legder(inv[:, j])) for j in range(m + 1)], axis=1)
    return s, phi, dphi, 0.5 * w


def run_polynomial(u, v, s2, n, tol, max_iter, degree=4):
    """LM (same damping rules as the library) on polynomial-in-time paths with the dense exact Hessian."""
    model = AlphaPathMetric(s2)
    nq = 3 * degree  # Gauss–Legendre nodes in time (the energy with 4× as many is reported)
    s, phi, dphi, wq = polynomial_basis(degree, nq)
    k, d = u.shape

    def evaluate(c, full=True):
        th, vel = np.einsum("qj,jkd->qkd", phi, c), np.einsum("qj,jkd->qkd", dphi, c)
        if not full:
            return float(wq @ model.qform(th, vel, None))
        q, dt, dv = model.qform_grad(th, vel, None)
        g = (np.einsum("q,qj,qkd->jkd", wq, phi, dt) + np.einsum("q,qj,qkd->jkd", wq, dphi, dv))[1:-1].ravel()
        a, b, cc = model.qform_hessian(th, vel, None)
        p, dp = phi[:, 1:-1], dphi[:, 1:-1]
        h = (np.einsum("q,qj,qk,qab->jakb", wq, p, p, a) + np.einsum("q,qj,qk,qab->jakb", wq, p, dp, b)
             + np.einsum("q,qj,qk,qba->jakb", wq, dp, p, b) + np.einsum("q,qj,qk,qab->jakb", wq, dp, dp, cc))
        return float(wq @ q), g, h.reshape(len(g), len(g))

    c = (1 - s)[:, None, None] * u + s[:, None, None] * v
    e, g, h = evaluate(c)
    lam, it, certified = 1e-3, 0, False
    while it < max_iter:
        dec = newton_decrement(h, g)
        if dec is not None and dec < tol * e:
            certified = True
            break
        it += 1
        scale = float(np.mean(np.diag(h)))
        for _ in range(60):
            try:
                step = -cho_solve(cho_factor(h + lam * scale * np.eye(len(h))), g)
            except np.linalg.LinAlgError:
                lam *= 2
                continue
            pred = -g @ step - 0.5 * step @ h @ step
            trial = c.copy()
            trial[1:-1] += step.reshape(degree - 1, k, d)
            e_trial = evaluate(trial, full=False)
            if e_trial < e:
                rho = (e - e_trial) / pred if pred > 0 else 0.0
                lam = max(lam / 3 if rho > 0.75 else (lam * 4 if rho < 0.25 else lam), 1e-14)
                break
            lam *= 10
        else:
            break
        c = trial
        e, g, h = evaluate(c)
    _, phi4, dphi4, wq4 = polynomial_basis(degree, 4 * nq)
    th4, vel4 = np.einsum("qj,jkd->qkd", phi4, c), np.einsum("qj,jkd->qkd", dphi4, c)
    e4 = float(wq4 @ model.qform(th4, vel4, None))
    return {"iterations": it, "energy": e, "certified": certified, "degree": degree, "time_nodes": nq,
            "unknowns": (degree - 1) * k * d, "energy_with_4x_time_nodes": e4}


RUNNERS = {"lm": run_lm, "coarse_to_fine": run_coarse_to_fine, "trust_exact": run_trust_exact,
           "saddle_free": run_saddle_free, "polynomial": run_polynomial}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sigma2", type=float, default=0.5)
    ap.add_argument("--n-steps", type=int, default=16)
    ap.add_argument("--tol", type=float, default=1e-9)
    ap.add_argument("--max-iter", type=int, default=300)
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    ap.add_argument("--quick", action="store_true", help="n_steps 4, 3 iterations: checks that the script runs")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--record", action="store_true",
                    help="write the results, machine and date to docs/_data/benchmarks/bench_solvers.json (docs: Performance)")
    args = ap.parse_args(argv)
    if args.quick and args.record:
        ap.error("--record: a --quick run is a smoke test, not a measurement")
    if args.quick:
        args.n_steps, args.max_iter = 4, 3
    shapes, ids = load_corpus_callosum()
    x = to_centroid_size(shapes)
    u, v = x[list(ids).index(1)], x[list(ids).index(2)]
    bound2 = AlphaPathMetric(args.sigma2).lower_bound(u, v) ** 2
    report = {"sigma2": args.sigma2, "n_steps": args.n_steps, "tol": args.tol, "max_iter": args.max_iter,
              "K": len(u), "lower_bound_squared": bound2, "methods": {}}
    print(f"α geodesic, CC 1–2, K = {len(u)}, σ² = {args.sigma2}, n_steps = {args.n_steps}, "
          f"certificate: Newton decrement < {args.tol:g}·E, at most {args.max_iter} iterations")
    with warnings.catch_warnings(), one_blas_thread():
        warnings.simplefilter("ignore", G.GeodesicWarning)
        for name in args.methods:
            t0 = time.perf_counter()
            out = RUNNERS[name](u, v, args.sigma2, args.n_steps, args.tol, args.max_iter)
            out["seconds"] = time.perf_counter() - t0
            out["energy_over_bound_squared_minus_1"] = out["energy"] / bound2 - 1
            report["methods"][name] = out
            print(f"{name:>15}: {out['seconds']:8.1f} s  {out['iterations']:4d} it  certified={out['certified']!s:5}  "
                  f"energy={out['energy']:.9e}  (E/bound² − 1 = {out['energy_over_bound_squared_minus_1']:.2e})",
                  flush=True)
    if args.json:
        args.json.write_text(json.dumps(report, indent=1) + "\n")
    if args.record:
        print(f"recorded {record('bench_solvers', report, argv=argv)}")
    return report


if __name__ == "__main__":
    main()
