"""The non-rigid registration's search: starts over every rotation, a short EM from each, the best
few carried to convergence at each candidate outlier weight, the fit of least negative log-posterior
(with prices on the outlier weight and on the pose's turn) kept, and what the other fits say about it.

The equations are in :mod:`shapelib.pointsets._coherent_em`; this module decides where EM starts
and which of its fits is the answer. Both sets come in normalised units (zero mean, unit RMS radius).

1. **Starts.** The source turned by every rotation of a fixed set (2-D: every 22.5°; 3-D: the 24
   rotations of the cube), and their mirror images when reflections are allowed. EM's basin of
   attraction reaches further than half the step (CPD recovers rotations up to about 70° on its
   own), so one start lies in the right basin whatever the target's orientation. In 3-D, with known
   correspondences (``landmarks``), the rotation that takes the source's landmarks onto the target's
   is one more start, carried to the final fits besides the best of the others: on a near-symmetric
   3-D surface the cube's rotations can lead to another pose that the landmarks alone, a few points
   among hundreds in the E-step, do not pull back.
2. **Screening.** ``SCREEN_ITER`` EM iterations from each start at the screening outlier weight
   (plain EM: the acceleration of :func:`~._coherent_em.run_em` starts after them), with the kernel
   truncated at ``SCREEN_EIG_RTOL`` (a coarser deformation, which ranks the starts as well); the
   ``N_KEEP`` starts of least objective go on, and the source as given (rotation 0) with them when it
   is not one of them. After 40 iterations a start turned away from the target can lead, its fold not
   yet paid for, while the source as given wins once both have converged: carried to the final fits,
   it took samples 1–5 of the Chui–Rangarajan benchmark from 20 to 14 failures (mean error 0.0229 →
   0.0175) and samples 6–10, not used to choose it, from 25 to 22 (0.0203 → 0.0171; 21 with the
   screening's truncated kernel), with no failure
   of the rotation levels (where the source as given is the wrong pose) and every failure still
   flagged; about 10 % more time, which the screening's truncated kernel saves again.
3. **Outlier weight.** With ``w="auto"``, each kept start is continued to convergence at every
   weight of ``W_GRID`` and the fit of least ``F + W_COST · m · w`` (:func:`criterion`; ``F`` is the
   negative log-posterior, a likelihood of the same target data under each fit) is kept: the profile
   likelihood of ``w`` over a grid, with a price on each target point given up to the outliers. Each fit runs at its own fixed ``w`` — EM that also updates ``w`` feeds back (what
   the deformation has not reached yet is called an outlier and then never reached), which is
   what a fixed weight per fit avoids. The fit at the screening weight continues the screening's
   EM (with the full kernel, from the same means: the truncated kernel's eigenvectors are a subset of
   the full kernel's); the others start again from the posed source.
4. **The price on the pose's rotation.** Each final fit's objective is the negative log-posterior plus
   ``POSE_PRIOR`` nats per source point times ``1 − cos φ`` for the fit's turn φ (:func:`with_pose_prior`):
   of two fits that explain the target about equally well, the one that turns the source less wins. A
   fish or a character turned by 90°–180° and slid along its own outline can explain a noisy or
   occluded target a few nats better than the right pose; on the rotation levels the right pose leads
   by far more than the largest price. Chosen with ``W_COST`` on samples 1–5 of the Chui–Rangarajan
   benchmark: 14 → 11 failures, mean error 0.0175 → 0.0128; on samples 6–10, not used to choose them,
   21 → 17 failures, 0.0171 → 0.0137.
5. **The comparison after the fit** (:func:`assess`): every final fit is kept with its objective, so
   that two distinct fits of nearly equal objective (a near-symmetric shape) are seen.

**Threads.** The starts are independent of each other, and so are the final fits: :func:`fit_all`
runs each group on ``n_threads`` threads (the compiled EM loop and the objective release the GIL)
and keeps the results in the order of a run in one thread, so that the answer does not depend on the
number of threads. Measured on a 2-core machine (AMD EPYC; sample 1 of the 56 Chui–Rangarajan
levels), one thread against two: the screening 14.1 → 9.8 ms, the final fits 8.3 → 5.0 ms per
registration (1.4–1.7×, not 2×).

**Cost.** A registration of two sets of ~100 points runs about 1,000 EM iterations: the screening's
16 × ``SCREEN_ITER`` (about 630) and the final fits' (about 370), 90 % of its time in one thread. One
iteration takes ~20 µs on a 2-core AMD EPYC (fish, 98 points, kernel rank 27): the E-step ~12 µs
(its exponentials vectorised, :func:`~._coherent_em._exp_neg`, and each column's smallest distance
taken as an integer minimum, :func:`~._coherent_em._column`), the M-step ~6 µs (the k × k system by
Cholesky, ``G W = Q z`` carried to the next E-step: :func:`~._coherent_em._m_step`). Both are
written out as loops that the compiler vectorises. Measured on sample 1 (two threads, same
machine), the median registration went from 22.8 ms to 17.0 ms with the M-step's BLAS and LAPACK
calls written out (per-call costs dominate products this small, and calls from two threads
contend; the M-step alone 11 → 6 µs), to 16.4 ms with the σ² update's dot products too, and to
13.1 ms with the E-step's integer minimum and rounding by a shift (17.4 → 12 µs); every error of
samples 1–10 within 3e-10 of before. ``EIG_RTOL`` at 1e-8 instead of 1e-10 (rank 37) took the median registration
from 28.6 to 19.8 ms before that. Cheaper searches, measured on samples 1–5 of the
Chui–Rangarajan benchmark (280 registrations; failures are errors above 0.05; the defaults, with
those three weights: 27 failures, mean error 0.0257); none kept the accuracy and halved the time — those that saved a
quarter or more lost accuracy, those that kept it saved a few per cent:

* successive halving (16 starts for 10 iterations, the best 8 to 20, the best 4 to 40; or 16 to
  15, the best 6 to 40): 31 or 29 failures, mean error 0.0327 or 0.0275, 30 % less time;
* the starts ranked before any EM by the overlap of the turned source with the target
  (``Σ_ij exp(−|R x_i − y_j|² / 4s²)``, the cross term of the rigid L² distance, at s² = 0.05 or
  0.2), the best 8 or 6 of the 16 screened: 36–39 or 47–59 failures, mean error 0.037–0.063,
  30–40 % less time — a rigid score picks the wrong starts for a deformed, noisy or occluded target;
* the screening on farthest-point subsets of 50 points (λ as given or scaled with the subset's
  size): 46–51 failures;
* one start carried to the final fits instead of two: 31 failures, 10 of them not flagged (the
  ambiguity check of :func:`assess` needs a second start);
* with the four weights of ``W_GRID`` (24 failures on samples 1–5, 27 on 6–10): the second start
  fitted at the screening weight only (five final fits instead of eight): 28 and 34 failures, 3
  and 2 of them not flagged, 16 % less time; 30 screening iterations instead of 40: 24 and 33
  failures (mean error 0.0267 and 0.0235 against 0.0245 and 0.0205), 11 % less time;
* dropping, after 20 or 30 iterations, only the starts whose objective exceeds the second best's by
  more than 2–3 per target point: no registration's best two starts change, but it saves 1–5 % of
  the screening (starts this far behind are few);
* the kernel's eigenvalues truncated at 1e-8 or 1e-7 of the largest instead of 1e-10, with the
  M-step's LU solve of then: the same fits to 1e-4 and under 5 % less time (with the Cholesky
  M-step, 1e-8 is ``EIG_RTOL``).

Scoring the final fits by another criterion instead of ``F`` did not help either: the L²
(L2E) fit of the moved source mixture to the target at the target's σ², at its point spacing or
at the fit's own σ² (36, 29 or 43 failures), or the least deformation among the fits within
0.02–1 of the least ``F`` per target point (28–58). Fewer starts — 12, 10 or 8 (every 30°, 36°,
45°), on two threads 24, 23 and 22 ms against 28 ms for 16 — kept the accuracy of samples 1–5 at
12 (25 failures, mean error 0.0261) but not on the tests' synthetic cases: with 12 starts a known
smooth deformation, a similarity and a near-symmetric shape's flag were no longer recovered.

The stiffness ``λ`` stays fixed (``register``'s ``lam``; σ² scales the deformation's share of each
M-step already). Fixed ``λ`` = 1, 2, 4, 8 on the same 280 registrations: 27, 24, 25, 28 failures
(mean error 0.0276, 0.0245, 0.0245, 0.0314), and on samples 6–10 36, 27, 30, 39 (0.0234, 0.0205,
0.0222, 0.0276); with the earlier three weights 30, 27, 29, 30 and 38, 29, 33, 39. A larger ``λ``
is better for the occluded fish on both halves (``λ`` = 4: mean error 0.010 and 0.022 against 0.020
and 0.034), not for the occluded character; under noise and outliers the best ``λ`` differs between
the fish and the character and between the halves. Chosen per pair, no criterion picked it well. The
kernel's width is not a better lever (``sigma2_metric`` = 1, 1.5, 2, 3: 40, 28, 27, 31 failures).

* The two kept starts' final fits at every ``λ`` of {1, 2, 4} (18 fits instead of 6), the fit of
  least ``F`` plus the Laplace approximation's Occam term ``(d/2) log det(I + G diag(P1)/λσ²)``
  (the evidence of ``λ``, type-II maximum likelihood): 24 failures but mean error 0.0272; by ``F``
  alone: 25, 0.0262; three times the final fits' cost.
* The best fit continued from its own coefficients at ``λ`` = 1 and 4, either criterion: 27
  failures, 0.0253.
* Three complete searches at ``λ`` = 1, 2, 4, the fit of least ``F``: 20 failures, 0.0217, for three
  times the time. The gain is the other screenings' starts (the final fits at the three ``λ`` from
  the ``λ`` = 2 screening above gain nothing), i.e. more search, not a better stiffness; and
  carrying three starts instead of two (``N_KEEP`` = 3) to the final fits gives 28 failures, 0.0264:
  where the search fails, the wrong fit has the least ``F``. Nor did the gain hold on other draws: a
  second pair of searches (``λ`` = 1 and 4) run only when the first registration is flagged, the fit
  of least ``F`` kept, took samples 1–5 from 27 to 19 failures (mean error 0.0257 → 0.0220) but
  left samples 6–10 at 29 (0.0211 → 0.0209), for half as much CPU again on average (a quarter of
  the registrations are flagged).
* Dropping, after 15 or 25 screening iterations, a start whose fit is within 0.02–0.1 (mean
  distance) of a start of lower objective: at 0.02 none is dropped (the fits have not met yet); at
  0.05–0.1, 6–16 % of the starts are dropped but the best fit is lost in 3–7 of the 56 registrations
  of sample 1.
* Each source component's mixing weight learned by EM (``π_i ∝ Σ_j P_ij``, with or without a
  Dirichlet pseudo-count of 1), so that an occluded part's components could drop out: on the 60
  occlusion registrations of samples 1–5, in a plain-EM prototype, 27 or 21 failures against 22 with
  equal weights.
"""

from __future__ import annotations

import contextlib
import itertools
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..geometry.procrustes import optimal_rotation
from ._coherent_em import EMState, Kernel, box_volume, initial_sigma2, objective, posteriors, run_em

#: rotation starts in 2-D (every 360/N degrees)
N_ROT_2D = 16
#: EM iterations from every start before the best are kept
SCREEN_ITER = 40
#: starts carried to convergence (besides the source as given: step 2)
N_KEEP = 2
#: the screening's kernel keeps the eigenvalues above this fraction of the largest (the final fits'
#: ``EIG_RTOL``, 1e-8): a coarser deformation ranks the starts as well, in less time. The fish's
#: 98-point kernel keeps rank 15 instead of 27. Chosen on samples 1–5 of the Chui–Rangarajan benchmark
#: (with the source as given carried: 1e-8, 1e-6, 1e-5, 1e-4, 1e-3: 14, 14, 14, 14, 16 failures, mean
#: error 0.0175 but 0.0177 at 1e-3; false alarms 6.5, 6.5, 5.6, 6.5, 5.6 %; median 15.4, 14.6, 14.0,
#: 13.6, 13.9 ms): of those that keep the accuracy, the one with the fewest false alarms, a factor 100
#: from the first that loses it
SCREEN_EIG_RTOL = 1e-5
#: the outlier weight of the screening
W_SCREEN = 0.2
#: the outlier weights compared when ``w="auto"`` (0.01 added to 0.05, 0.2 and 0.5: on samples 1–5 of
#: the Chui–Rangarajan benchmark 27 → 24 failures, mean error 0.0257 → 0.0245; on samples 6–10,
#: not used to choose it, 29 → 27 and 0.0211 → 0.0205; 8–10 % more time)
W_GRID = (0.01, 0.05, 0.2, 0.5)
#: what calling a target point an outlier costs in the comparison of fits, in nats per target point
#: and unit of outlier weight: fits are ranked by ``F + W_COST · m · w`` (:func:`criterion`). Without it
#: the profile likelihood of ``w`` prefers the largest weight too often: the uniform component takes
#: the part of the target the deformation has not reached, and the fit stops there (an occluded or
#: noisy target fitted at ``w`` = 0.5 with errors two to five times those of its fit at 0.2 or 0.05).
#: Chosen with ``POSE_PRIOR`` on samples 1–5 of the Chui–Rangarajan benchmark, by re-ranking every final
#: fit of the search (W_COST 0.15–0.5 × ``POSE_PRIOR`` 0.04–0.2 per source point: the fewest failures, then
#: the least mean error, at 0.3 and 0.12: 11 failures, 0.0128; at 0.15 without the price on the turn 14,
#: 0.0175; 0.25 or 0.35 with 0.12: 12 and 11 failures, 0.0136 and 0.0128). Without the rotation prior the weight's price was flat from 0.15 to 0.6
#: (14 failures each); with it the larger price stops the occluded character's fits at ``w`` = 0.5
W_COST = 0.3
#: κ, in nats per source point, of the price on the rotation of each fit's pose (the rotation part of the
#: similarity of least squares from the source as given onto the fitted points): ``κ n (d − tr R) / 2``
#: for ``n`` source points, in 2-D ``κ n (1 − cos φ)`` — κ per point at a quarter turn, 2κ at a half turn.
#: The log-density of a matrix von Mises–Fisher distribution centred on the source's own orientation
#: (C. G. Khatri and K. V. Mardia, *Journal of the Royal Statistical Society B* 39(1), 95–106, 1977),
#: with a concentration that grows with the set as the likelihood does, so that how far the data must
#: outweigh it per point does not depend on the sets' size (as ``W_COST``'s price is per target point).
#: Added to each final fit's objective (:func:`with_pose_prior`): of two fits that explain the target
#: about equally well, the one that turns the source less wins. On the benchmark's rotation levels
#: (30°–180°) the right pose leads the best fit within 45° of the source's orientation by 0.35–8.5
#: nats per point; the failures it mends are noisy, occluded or strongly deformed targets where a fish
#: or character turned by 90°–180° and slid along its own outline explains the target better by 3–32
#: nats (0.03–0.6 per target point). Chosen with ``W_COST`` on samples 1–5 (``register``'s
#: ``pose_prior``; 0 for no price, the fits compared by how well they explain the target alone, as the
#: registration distance needs). A total price
#: of 12 nats, the same on the benchmark's ~100-point sets, turned a 20-point fish rotated by 126° into
#: a failure: a fixed prior outweighs the data of a small set
POSE_PRIOR = 0.12


def criterion(f, w, m):
    """The score by which fits are compared (least first): the objective ``f`` (``F`` of
    :mod:`~shapelib.pointsets._coherent_em`, the negative log-posterior at the fit's own outlier
    weight ``w``) plus ``W_COST · m · w`` for a target of ``m`` points: a larger outlier weight must
    explain the target better by ``W_COST`` nats for each point it gives up. With one weight for
    every fit (``w`` given), the order of ``F``."""
    return f + W_COST * m * w


def turn(xn, theta, reflection):
    """``(d − tr R) / 2`` for the orthogonal ``R`` (a rotation, or with ``reflection`` any orthogonal map) of
    the similarity of least squares taking the source ``xn`` (n, d) onto the fitted points ``theta``
    (:func:`~shapelib.geometry.procrustes.optimal_rotation`): ``1 − cos φ`` for a rotation by φ in 2-D or
    about an axis in 3-D; 0 for none, 2 for a half turn."""
    # θ needs no centring: Σ_i θ_iᵀ (x_i − x̄) = Σ_i (θ_i − θ̄)ᵀ (x_i − x̄), the source's centred rows summing to 0
    r, _ = optimal_rotation(theta, xn - xn.mean(axis=0), reflection=reflection)
    return 0.5 * (xn.shape[1] - float(np.trace(r)))


def with_pose_prior(fits, xn, pose_prior, reflection):
    """``fits`` (``(objective, start, EMState)``) with ``pose_prior · n · turn`` (:func:`turn`,
    ``POSE_PRIOR``; ``n`` source points) added to each objective: the price on the pose's rotation. As
    given when ``pose_prior`` is 0."""
    if pose_prior == 0:
        return list(fits)
    n = len(xn)
    return [(f + pose_prior * n * turn(xn, st.theta, reflection), k, st) for f, k, st in fits]


def ranked(fits, m):
    """``fits`` (``(objective, start, EMState)``) sorted by :func:`criterion`, best first (stable)."""
    return sorted(fits, key=lambda c: criterion(c[0], c[2].w, m))


def cube_rotations():
    """The 24 proper rotations of the cube: signed permutation matrices of determinant +1."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            r = np.zeros((3, 3))
            r[np.arange(3), perm] = signs
            if np.linalg.det(r) > 0:
                out.append(r)
    return out


def _truncated_each(kernels, rtol):
    """``kernels`` truncated at ``rtol`` (:meth:`~shapelib.pointsets._coherent_em.Kernel.truncated`),
    each distinct kernel once (a weight-coordinate kernel is one object for every rotation)."""
    done = {}
    for k in kernels:
        if id(k) not in done:
            done[id(k)] = k.truncated(rtol)
    return [done[id(k)] for k in kernels]


@contextlib.contextmanager
def _pool(n_threads):
    """``run(f, items)``: the results of ``f`` over ``items`` in order, as each arrives, on ``n_threads``
    threads (the compiled EM releases the GIL), or in this thread when ``n_threads`` is 1."""
    if n_threads <= 1:
        yield map
        return
    pool = ThreadPoolExecutor(max_workers=n_threads, thread_name_prefix="shapelib-register")
    try:
        yield pool.map
    finally:  # on an error or Ctrl-C: the fits not started are dropped, the running ones end, no thread stays
        pool.shutdown(wait=True, cancel_futures=True)


def start_rotations(d, reflection):
    """The start rotations (d, d) of step 1 (with the mirror images after them if asked)."""
    if d == 2:
        a = 2 * np.pi * np.arange(N_ROT_2D) / N_ROT_2D
        rots = [np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]) for t in a]
    else:
        rots = cube_rotations()
    if reflection:
        mirror = np.diag([1.0] * (d - 1) + [-1.0])
        rots = rots + [r @ mirror for r in rots]
    return rots


def landmark_rotation(xn, yn, labels, reflection):
    """The rotation ``R`` (d, d) of least squares taking the known source landmarks onto theirs in the
    target, ``(x_i − x̄) Rᵀ ≈ y_j − ȳ`` over the pairs of ``labels`` (each about its landmarks' centroid:
    ordinary Procrustes, :func:`~shapelib.geometry.procrustes.optimal_rotation`), or None with fewer than
    two pairs or pairs that coincide on one side."""
    j = np.flatnonzero(labels >= 0)  # label_array's empty array when none is known: no pair
    if len(j) < 2:
        return None
    a = yn[j] - yn[j].mean(axis=0)
    b = xn[labels[j]] - xn[labels[j]].mean(axis=0)
    if min(float(np.sum(a * a)), float(np.sum(b * b))) < 1e-24:
        return None
    r, _ = optimal_rotation(a, b, reflection=reflection)  # a ≈ b r
    return r.T


def fit_all(xn, yn, *, kernel_of, lam, w, fixed_s2, reflection, max_iter, tol, s2_floor, progress=None,
            volume=None, labels=None, n_threads=1, pose_prior=POSE_PRIOR):
    """Steps 1–4: every final fit as ``(objective, start index, EMState)``, best first, and the starts.

    ``kernel_of(u)`` gives the :class:`~shapelib.pointsets._coherent_em.Kernel` at a posed source (a
    weight-coordinate kernel is the same for every rotation: ``kernel_of`` may return a cached one);
    ``w`` is a number, or None for the grid of step 3. ``progress(done, total)``, if given, is called
    after each start's screening and each final fit; ``total`` counts the source as given among the
    kept starts until the screening says whether it is one of the ``N_KEEP`` best already (then it
    shrinks by one start's fits). The screening runs with each kernel truncated at
    ``SCREEN_EIG_RTOL``, the final fits with ``kernel_of``'s. ``volume`` is the target's :func:`box_volume`
    if the caller has it; ``labels`` the known correspondences
    (:func:`~shapelib.pointsets._coherent_em.label_array`), in every E-step and objective; in 3-D, with
    two or more, the rotation that takes the source landmarks onto the target's
    (:func:`landmark_rotation`) is one more start, the last, carried to the final fits besides the
    ``N_KEEP`` best of the others: the fits compared are a search's without it, and its own. Each
    final fit's objective includes the prior on its pose's rotation (:func:`with_pose_prior`,
    ``pose_prior``); the screening's does not.
    """
    d = xn.shape[1]
    volume = box_volume(yn) if volume is None else volume
    rots = start_rotations(d, reflection)
    n_grid = len(rots)
    # 3-D only: in 2-D a start of the grid lies within 11.25° of it already (measured on the 2-D benchmark
    # with 2 and 3 landmarks, samples 1–10: 22 and 17 failures with it against 22 and 16, 20 % more time)
    known = landmark_rotation(xn, yn, labels, reflection) if labels is not None and d == 3 else None
    if known is not None:
        rots = rots + [known]
    screen_w = W_SCREEN if w is None else w
    grid = W_GRID if w is None else (w,)
    opts = dict(lam=lam, volume=volume, tol=tol, fixed_s2=fixed_s2, s2_floor=s2_floor, labels=labels)
    # at most: the source as given is carried besides the N_KEEP best unless it is one of them (then the
    # total shrinks once, after the screening)
    total = len(rots) + (N_KEEP + 1 + len(rots) - n_grid) * len(grid)
    tick = progress if progress is not None else (lambda done, total: None)

    def screen(k):
        u = xn @ rots[k].T
        s2 = fixed_s2 if fixed_s2 is not None else initial_sigma2(u, yn)
        st = EMState(u=u, kernel=screen_kernels[k], coef=np.zeros_like(u), s2=s2, w=screen_w)
        run_em(st, yn, max_iter=min(SCREEN_ITER, max_iter), **opts)
        return objective(st, yn, lam=lam, volume=volume, labels=labels), k, st

    def final(job):
        k, st0, wk = job
        if wk == screen_w:  # the screening's EM, continued to convergence (or max_iter in all)
            same = st0.kernel is kernels[k]  # (the screening's truncation dropped nothing)
            coef = st0.coef.copy() if same else st0.kernel.in_range(st0.coef)  # the same means, full kernel
            st = EMState(u=st0.u, kernel=kernels[k], coef=coef, s2=st0.s2, w=wk, it=st0.it, ok=st0.ok, why=st0.why)
            if not (st.ok and same):
                # a fit that met the tolerance with the screening's kernel goes on with the full one: the
                # screening's fixed point is not the final fits' EM's
                st.ok, st.why = False, "max_iter"
                run_em(st, yn, max_iter=max_iter - st.it, **opts)
        else:  # each other weight from the start: a fit continued from another weight's keeps its basin
            s2 = fixed_s2 if fixed_s2 is not None else initial_sigma2(st0.u, yn)
            st = EMState(u=st0.u, kernel=kernels[k], coef=np.zeros_like(st0.u), s2=s2, w=wk)
            run_em(st, yn, max_iter=max_iter, **opts)
        return objective(st, yn, lam=lam, volume=volume, labels=labels), k, st

    kernels = [kernel_of(xn @ r.T) for r in rots]  # in this thread: kernel_of may cache
    screen_kernels = _truncated_each(kernels, SCREEN_EIG_RTOL)
    with _pool(n_threads) as run:
        screened = []
        for c in run(screen, range(len(rots))):
            screened.append(c)
            tick(len(screened), total)
        screened.sort(key=lambda c: c[0])
        # the landmarks' start goes on besides the N_KEEP best of the others: the fits compared are those
        # of a search without it and its own
        extra = [c for c in screened if c[1] >= n_grid]
        best = [c for c in screened if c[1] < n_grid][:N_KEEP]
        # the source as given (rotation 0 of the grid) goes on too, when it is not among them (step 2)
        given = [] if any(k == 0 for _, k, _ in best) else [c for c in screened if c[1] == 0]
        kept = best + given + extra
        jobs = [(k, st0, wk) for _, k, st0 in kept for wk in grid]
        total = len(rots) + len(jobs)
        # the fits that start afresh first, the continued ones (shorter) last: the threads finish together
        order = sorted(range(len(jobs)), key=lambda i: jobs[i][2] == screen_w)
        fits = [None] * len(jobs)
        for done, (i, c) in enumerate(zip(order, run(final, [jobs[i] for i in order])), start=1):
            fits[i] = c
            tick(len(rots) + done, total)
    return ranked(with_pose_prior(fits, xn, pose_prior, reflection), len(yn)), rots, screened


#: two fits are distinct when their points differ by more than this (mean distance, normalised units)
DISTINCT = 0.1
#: …and nearly equal when their objectives differ by less than this per target point (chosen on
#: samples 1–5 of the Chui–Rangarajan benchmark, with ``W_GRID``: the failed fits that only this
#: check flags have a distinct fit within 0.018–0.070 per target point, the good fits' nearest
#: distinct fits are 0.043 or 0.159 and more away; every threshold from 0.071 to 0.159 catches every
#: failure with the fewest false alarms, and the largest round one of them leans towards catching.
#: On samples 6–10 the failures' gaps reach 0.105: 0.15 still catches all of them. With the price on the
#: turn and ``W_COST`` = 0.3 the gap is measured without the price, and 0.15 catches every failure of
#: samples 1–5 and 6–10 with 11 false alarms of 216 and 214 good fits)
AMBIGUOUS_PER_POINT = 0.15
#: the fit leaves the target unexplained when σ exceeds this many target point spacings
RESIDUAL_SPACINGS = 2.0
#: the fit misses a part when more than this share of the source points explains no target point (a
#: third: chosen on samples 1–5 of the Chui–Rangarajan benchmark and samples 1–2 of the 3-D surfaces
#: of ``benchmarks/bench_registration_3d.py``, where 7 of the 9 failed fits a half let through
#: left 0.38–0.49 of the source unmatched, the other two 0.28–0.29, and the good fits at most 0.23)
UNMATCHED_SHARE = 1 / 3


def assess(fits, yn, *, spacing2, volume=None, labels=None, xn=None, pose_prior=0.0, reflection=False):
    """Step 5: why the best fit probably failed (an empty list when nothing says so).

    * another start's fit, distinct from the best (``DISTINCT``), explains the target within
      ``AMBIGUOUS_PER_POINT`` per target point of the best, or better (:func:`criterion` of the
      objectives without the prior on the pose, which chose between them): two poses explain the target
      about equally well;
    * σ of the fit above ``RESIDUAL_SPACINGS`` target point spacings: the deformation leaves most
      of the target unexplained;
    * more than ``UNMATCHED_SHARE`` of the source points with less than half a target point each.

    ``volume`` is the target's :func:`box_volume` if the caller has it; ``labels`` the known
    correspondences; ``xn``, ``pose_prior`` and ``reflection`` those of :func:`with_pose_prior` when the
    objectives include its prior.
    """
    f0, k0, best = fits[0]
    m = len(yn)

    def explains(f, st):  # the fit's score without the prior on its pose
        return criterion(f - (pose_prior * len(xn) * turn(xn, st.theta, reflection) if pose_prior else 0.0), st.w, m)

    c0 = explains(f0, best)
    theta = best.theta
    reasons = []
    for f, k, st in fits[1:]:
        if k == k0:
            continue
        gap = (explains(f, st) - c0) / m
        if gap < AMBIGUOUS_PER_POINT and np.mean(np.linalg.norm(st.theta - theta, axis=1)) > DISTINCT:
            reasons.append(f"another pose explains the target almost as well (score {gap:.3f} per target "
                           f"point higher) with a different fit" if gap >= 0 else
                           f"another pose explains the target better (score {-gap:.3f} per target point "
                           f"lower) with a different fit, turned further from the source as given")
            break
    ratio = float(np.sqrt(best.s2 / spacing2))
    if ratio > RESIDUAL_SPACINGS:
        reasons.append(f"the fit leaves sigma = {ratio:.2f} target point spacings")
    p1 = posteriors(theta, yn, best.s2, best.w, box_volume(yn) if volume is None else volume, labels).sum(axis=1)
    share = float(np.mean(p1 < 0.5))
    if share > UNMATCHED_SHARE:
        reasons.append(f"{100 * share:.0f} % of the source points match no target point")
    return reasons, {"sigma_over_spacing": ratio, "unmatched_source_share": share}


def refit(u, yn, w, kernel_of, *, volume, lam, fixed_s2, max_iter, tol, s2_floor, labels=None):
    """EM from the posed source ``u`` with another kernel, at the outlier weight ``w`` of the search."""
    s2 = fixed_s2 if fixed_s2 is not None else initial_sigma2(u, yn)
    st = EMState(u=u, kernel=kernel_of(u), coef=np.zeros_like(u), s2=s2, w=w)
    return run_em(st, yn, lam=lam, volume=volume, max_iter=max_iter, tol=tol, fixed_s2=fixed_s2, s2_floor=s2_floor,
                  labels=labels)


def with_kernel(kernel_matrix_of, *, invariant):
    """``kernel_of(u)`` for :func:`fit_all`: an (n, n) kernel of the weight coordinates is factored
    (once, when ``invariant``: it does not change with a rotation of ``u``), an (n d, n d) kernel on
    the means is kept dense."""
    cache = {}

    def kernel_of(u):
        if invariant and "k" in cache:
            return cache["k"]
        g = kernel_matrix_of(u)
        cache["k"] = Kernel.of(g) if len(g) == len(u) else Kernel(full=g)
        return cache["k"]

    return kernel_of


__all__ = ["fit_all", "assess", "criterion", "ranked", "turn", "with_pose_prior", "POSE_PRIOR", "refit", "start_rotations", "landmark_rotation", "with_kernel", "W_GRID", "N_KEEP"]
