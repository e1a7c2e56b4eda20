# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Is the α geodesic distance more than gmmreg's L² distance? (σ² = 0.1)
#
# The α-order metric (eq. 22) is the pull-back of the flat L² metric on densities, so the
# geodesic distance is at least the L² chord `‖p_u − p_v‖` (what gmmreg minimises) and at most
# the length of any computed path. At σ² = 0.5 the two meet within 1e-3 on the corpus callosum
# pairs of Table I; at σ² = 0.1 the gap `length / chord − 1` does not close with solver
# iterations. Either the time discretisation (`n_steps`) keeps the path long, or the geodesic
# itself is longer than the chord — i.e. the manifold of GMM shapes curves away from the
# straight line in L², and the α distance is something more than the L² distance.
#
# We solve each pair to the solver's tolerance at n_steps = 4, 8, 16, 32, 64 (each level
# warm-started from the previous path with a point inserted in every segment), and extrapolate
# the gaps to n → ∞ (Richardson, order estimated from the last three levels).

# %% tags=["parameters"]
from shapelib.study import default_output_dir
output_dir = default_output_dir("alpha_discretisation")  # run_all.py passes its own
sigma2 = 0.1
n_steps_list = [4, 8, 16, 32, 64]
n_pairs = 21
tol = 1e-6
max_iter = 300
rtol = 1e-3

# %%
import itertools
import time
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from shapelib import distance_bracket, geodesic
from shapelib.solver.bracket import extrapolate_doublings, lower_bound, refine_path
from shapelib.datasets import load_corpus_callosum
from shapelib import to_centroid_size
from shapelib.study import pair_key, record_values, save_figure

shapes, paper_ids = load_corpus_callosum()
x = to_centroid_size(shapes)  # GPA (rotations), centroid size 20, as in Table I
pairs = list(itertools.combinations(range(len(x)), 2))[:n_pairs]
ns = sorted(int(n) for n in n_steps_list)
assert len(ns) >= 3 and all(b == 2 * a for a, b in zip(ns, ns[1:])), "n_steps_list: at least 3 successive doublings"


def refine(u, v):
    """Converged lengths at every n, each level warm-started from the previous path."""
    lengths, iters, path = [], [], None
    for n in ns:
        if path is not None:  # the same curve with a point inserted in every segment
            path = refine_path(path)
        with warnings.catch_warnings():  # convergence is recorded below instead
            warnings.simplefilter("ignore")
            r = geodesic(u, v, metric="alpha", sigma2=sigma2, n_steps=n, tol=tol, max_iter=max_iter, init=path)
        path = r.path
        lengths.append(r.length)
        iters.append((r.n_iter, bool(r.converged)))
    return np.array(lengths), iters


def richardson(gaps):
    """Limit and order of ``g(n) = g∞ + C n^-p`` from the last three doublings (order fitted,
    :func:`shapelib.solver.bracket.extrapolate_doublings`); order None if the differences do not
    decrease geometrically (then the last gap is returned)."""
    limit, order = extrapolate_doublings(gaps)
    return (gaps[-1], None) if limit is None else (limit, order)


t0 = time.perf_counter()
rows = []
for i, j in pairs:
    lb = lower_bound(x[i], x[j], metric="alpha", sigma2=sigma2)
    lengths, iters = refine(x[i], x[j])
    gaps = lengths / lb - 1.0
    limit, order = richardson(gaps)
    limit2 = gaps[-1] - (gaps[-2] - gaps[-1]) / 3.0  # fixed second order, for the spread
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        b = distance_bracket(x[i], x[j], metric="alpha", sigma2=sigma2, rtol=rtol)
    rows.append({"pair": tuple(sorted((int(paper_ids[i]), int(paper_ids[j])))), "lower": lb, "gaps": gaps,
                 "limit": limit, "order": order, "limit_p2": limit2, "iters": iters, "bracket": b})
seconds = time.perf_counter() - t0

# %%
G = np.array([r["gaps"] for r in rows])
limits = np.array([r["limit"] for r in rows])
limits_p2 = np.array([r["limit_p2"] for r in rows])
orders = np.array([np.nan if r["order"] is None else r["order"] for r in rows])
spread = np.abs(limits - limits_p2)  # how much the extrapolation depends on the assumed order
brackets = [r["bracket"] for r in rows]
# consistency: the bracket's certified interval contains the extrapolated distance lb (1 + g∞)
contains = [b.lower <= b.lower * (1 + g) <= b.upper * (1 + 1e-9) for b, g in zip(brackets, limits)]
measurable = limits > 3 * spread  # above the bound by more than 3× the extrapolation's spread
all_converged = all(c for r in rows for _, c in r["iters"])

for n, col in zip(ns, G.T):
    print(f"n = {n:3d}: gap median {np.median(col):.2e}, max {col.max():.2e}")
print(f"extrapolated gap: median {np.median(limits):.2e}, min {limits.min():.2e}, max {limits.max():.2e}; "
      f"order median {np.nanmedian(orders):.2f}; above {rtol:g}: {int(np.sum(limits > rtol))}/{len(rows)}")
print(f"brackets: {sum(b.converged for b in brackets)}/{len(rows)} reach {rtol:g}, "
      f"{sum(b.stopped_by == 'stalled' for b in brackets)} stalled; {seconds:.0f} s")

# %%
fig, ax = plt.subplots(figsize=(6, 4.2))
for r in rows:
    ax.loglog(ns, r["gaps"], "-o", ms=3, lw=0.8, color="0.5")
ax.loglog(ns, np.median(G, axis=0), "-o", color="k", lw=2, label="median over pairs")
ax.axhline(np.median(limits), color="C3", ls="--", label=f"median extrapolated limit {np.median(limits):.1e}")
ax.axhline(rtol, color="C0", ls=":", label=f"rtol {rtol:g}")
ax.set_xlabel("n_steps")
ax.set_ylabel("length / L² chord − 1")
ax.set_title(f"α geodesics of the corpus callosum pairs, σ² = {sigma2}")
ax.legend(fontsize=8)
save_figure(fig, output_dir, "alpha_gap_vs_n_steps")

# %%
values = {
    "alpha_discretisation/pairs": len(rows),
    "alpha_discretisation/n_steps_finest": ns[-1],
    "alpha_discretisation/gap_median_coarsest": float(np.median(G[:, 0])),
    "alpha_discretisation/gap_median_finest": float(np.median(G[:, -1])),
    "alpha_discretisation/gap_max_finest": float(G[:, -1].max()),
    "alpha_discretisation/limit_median": float(np.median(limits)),
    "alpha_discretisation/limit_min": float(limits.min()),
    "alpha_discretisation/limit_max": float(limits.max()),
    "alpha_discretisation/order_median": float(np.nanmedian(orders)) if np.isfinite(orders).any() else 0.0,
    "alpha_discretisation/pairs_limit_above_rtol": int(np.sum(limits > rtol)),
    "alpha_discretisation/pairs_measurably_above_bound": int(np.sum(measurable)),
    "alpha_discretisation/brackets_converged": int(sum(b.converged for b in brackets)),
    "alpha_discretisation/brackets_contain_limit": int(sum(contains)),
}
record_values(output_dir, values, notes={
    "alpha_discretisation": f"alpha metric, sigma2 = {sigma2}, corpus callosum pairs at centroid size 20; "
                            f"gap = length / L2 chord - 1 of converged geodesics (tol {tol:g}) at n_steps {ns}; "
                            "limit = Richardson extrapolation from the last three levels"},
    meta={"alpha_discretisation": {
        "sigma2": sigma2, "n_steps": ns, "seconds": seconds, "all_levels_converged": all_converged,
        "gap_median_by_n": {str(n): float(np.median(c)) for n, c in zip(ns, G.T)},
        "gap_max_by_n": {str(n): float(c.max()) for n, c in zip(ns, G.T)},
        "pairs": {pair_key("alpha_discretisation", "limit", *r["pair"]): {
            "gaps": r["gaps"], "limit": r["limit"], "limit_p2": r["limit_p2"],
            "order": r["order"] if r["order"] is not None else "n/a",
            "bracket": {"rel_gap": r["bracket"].rel_gap, "stopped_by": r["bracket"].stopped_by,
                        "n_steps": r["bracket"].n_steps}} for r in rows}}})

# %% [markdown]
# The report section below is generated from these numbers.

# %%
lines = [
    f"### Is the α geodesic distance more than the L² distance? (σ² = {sigma2})",
    "",
    f"`notebooks/alpha_discretisation.py`: α geodesics between the {len(rows)} corpus callosum pairs of Table I "
    f"(centroid size 20), solved to tol {tol:g} at n_steps = {', '.join(map(str, ns))} (warm-started); "
    f"gap = length / ‖p_u − p_v‖ − 1, where the L² chord ‖p_u − p_v‖ is gmmreg's distance and a lower bound.",
    "",
    "| n_steps | " + " | ".join(map(str, ns)) + " | n → ∞ (Richardson) |",
    "|---|" + "---|" * (len(ns) + 1),
    "| median gap | " + " | ".join(f"{np.median(c):.2e}" for c in G.T) + f" | {np.median(limits):.2e} |",
    "| max gap | " + " | ".join(f"{c.max():.2e}" for c in G.T) + f" | {limits.max():.2e} |",
    "",
]
verdict = ("measurably above" if np.sum(measurable) > len(rows) / 2 else "not measurably above")
shrink = G[:, -1] / G[:, -2]  # last doubling
lines += [
    f"The gap shrinks with n_steps at an estimated order {np.nanmedian(orders):.2f} (median; 2 would be the "
    f"order of a smooth path) and the last doubling removed a median {1 - np.median(shrink):.0%} of it: "
    f"extrapolated to n → ∞ the geodesic distance exceeds the L² chord by a median {np.median(limits):.2e} "
    f"(range {limits.min():.2e} to {limits.max():.2e}). For {int(np.sum(measurable))} of {len(rows)} pairs the "
    f"excess is more than three times the spread between the fitted-order and second-order extrapolations, "
    f"so at σ² = {sigma2} the α geodesic distance is **{verdict}** gmmreg's L² distance "
    f"(median excess {np.median(limits):.1e} relative). "
    f"{int(np.sum(limits > rtol))} of {len(rows)} pairs can therefore never be bracketed to {rtol:g}: "
    f"`distance_bracket(rtol={rtol:g})` reached it for {sum(b.converged for b in brackets)}, stopped "
    f"'stalled' for {sum(b.stopped_by == 'stalled' for b in brackets)}, and its certified interval contains "
    f"the extrapolated distance for {sum(contains)} of {len(rows)}.",
    "",
    f"All {len(rows) * len(ns)} geodesics converged: {all_converged}. Computed in {seconds:.0f} s.",
    "",
]
Path(output_dir).mkdir(parents=True, exist_ok=True)
Path(output_dir, "report_section.md").write_text("\n".join(lines))
print("\n".join(lines))
