# %% [markdown]
# # Shapes without landmarks — registration on the Chui–Rangarajan benchmark
#
# The paper closes with its next step: shapes as point sets whose mixture densities are compared
# without landmark correspondence, σ² estimated from the data. {func}`shapelib.register` registers
# a point set onto another of any size by the information geometry: a pose search over every
# rotation by the density distance, EM for σ², the outlier weight and the correspondences, and a
# deformation through the mixture's metric kernel whose path is an α geodesic
# ({doc}`/guide/pointsets`).
#
# Here it runs, with its defaults, beside the probabilistic registration methods that run here,
# each with its documented defaults on the same inputs normalised as MATLAB CPD does (zero mean,
# unit RMS radius; the result mapped back with the target's mean and scale): Coherent Point Drift
# (pycpd, deformable) and probreg's non-rigid CPD, FilterReg, GMMTree and BCPD. FilterReg and
# GMMTree are rigid only in probreg and take 3-D points: the 2-D sets are given to them with z = 0,
# on which GMMTree raises — a method that raises counts as a failure, its error that of the unmoved
# template. The data are the synthetic benchmark of Chui & Rangarajan: a fish (98 points) and a
# Chinese character (105 points), each degraded by deformation, noise, outliers, occlusion and
# rotation at 5 or 6 levels. The error of a method is the mean distance between the moved template
# points and their true positions; a registration fails when it exceeds 0.05. The curves below are
# error against level for every method, as in the CPD paper's figures; then one example of each
# degradation.

# %% tags=["parameters"]
from shapelib.study import default_output_dir
output_dir = default_output_dir("pointset_registration")  # run_all.py passes its own
levels = "all"  # or level names separated by commas, e.g. "fish_rot_1,fish_rot_4"
samples = 1  # samples per level (1 to 10)
methods = "all"  # or some of shapelib,cpd,probreg_cpd,probreg_filterreg,probreg_gmmtree,probreg_bcpd

# %%
import time
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from threadpoolctl import threadpool_limits

import shapelib as sl
from shapelib.datasets import TPS_RPM_LEVELS, load_tps_rpm_case
from shapelib.study import record_values, save_figure

names = list(TPS_RPM_LEVELS) if levels == "all" else [k.strip() for k in levels.split(",") if k.strip()]
LABELS = {"shapelib": "shapelib", "cpd": "pycpd CPD", "probreg_cpd": "probreg CPD", "probreg_filterreg": "FilterReg",
          "probreg_gmmtree": "GMMTree", "probreg_bcpd": "BCPD"}
used = list(LABELS) if methods == "all" else [m.strip() for m in methods.split(",") if m.strip()]
if not used or set(used) - set(LABELS):
    raise ValueError(f"methods: expected 'all' or some of {', '.join(LABELS)}, got {methods!r}")
FAILURE = 0.05


def normalise(a):
    m = a.mean(axis=0)
    s = float(np.sqrt(np.sum((a - m) ** 2) / len(a)))
    return (a - m) / s, m, s


def z0(a):  # a planar set as 3-D points, for the methods that take only those
    return np.c_[a, np.zeros(len(a))]


def peer(m, xn, yn):
    """A peer's moved template on normalised inputs, each with its defaults."""
    if m == "cpd":
        from pycpd import DeformableRegistration
        return DeformableRegistration(X=yn, Y=xn).register()[0]
    from probreg import bcpd, cpd, filterreg, gmmtree
    if m == "probreg_cpd":
        return cpd.registration_cpd(xn, yn, tf_type_name="nonrigid").transformation.transform(xn)
    if m == "probreg_filterreg":  # rigid only
        return np.asarray(filterreg.registration_filterreg(z0(xn), z0(yn)).transformation.transform(z0(xn)))[:, :2]
    if m == "probreg_gmmtree":  # rigid only, 3-D only
        return np.asarray(gmmtree.registration_gmmtree(z0(xn), z0(yn)).transformation.transform(z0(xn)))[:, :2]
    if m == "probreg_bcpd":
        return bcpd.registration_bcpd(xn, yn).transform(xn)
    raise ValueError(f"methods: unknown {m!r}")


def register(m, x1, y2a):
    """(moved template, seconds, the exception's class or None)."""
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")  # every method is judged by its error
            if m == "shapelib":
                out = np.asarray(sl.register(x1, y2a).points)
            else:
                (xn, _, _), (yn, my, sy) = normalise(x1), normalise(y2a)
                out = np.asarray(peer(m, xn, yn), dtype=float) * sy + my
        if not np.all(np.isfinite(out)):
            raise FloatingPointError("non-finite result")
        return out, time.perf_counter() - t0, None
    except Exception as exc:  # a peer that raises fails this registration
        return x1, time.perf_counter() - t0, type(exc).__name__


errors = {m: {} for m in used}
failures = {m: {} for m in used}
times = {m: [] for m in used}
raised = {m: {} for m in used}
moved = {}
with threadpool_limits(limits=1, user_api="blas"):  # every method on one BLAS thread
    for m in used:  # imports and first calls outside the timings
        register(m, load_tps_rpm_case(names[0], sample=1)["x1"], load_tps_rpm_case(names[0], sample=1)["y2a"])
    for name in names:
        for m in used:
            errors[m][name], failures[m][name] = [], 0
        for sample in range(1, samples + 1):
            case = load_tps_rpm_case(name, sample=sample)
            n = len(case["y2"])
            for m in used:
                out, seconds, exc = register(m, case["x1"], case["y2a"])
                times[m].append(seconds)
                err = float(np.mean(np.linalg.norm(out[:n] - case["y2"], axis=1)))
                errors[m][name].append(err)
                failures[m][name] += int(err > FAILURE or exc is not None)
                if exc is not None:
                    raised[m].setdefault(exc, 0)
                    raised[m][exc] += 1
                if sample == 1:
                    moved[(m, name)] = out
        print(f"{name:20s} " + "  ".join(f"{m} {np.mean(errors[m][name]):.4f}" for m in used))
mean_err = {m: {k: float(np.mean(v)) for k, v in errors[m].items()} for m in used}
print("raised:", {m: r for m, r in raised.items() if r} or "none")

# %% [markdown]
# ## Error against level

# %%
kinds = [("def", "deformation"), ("noise", "noise"), ("outlier", "outliers"), ("occlusion", "occlusion"),
         ("rot", "rotation")]
fig, axes = plt.subplots(2, 5, figsize=(16, 6), sharey="row")
for row, shape in enumerate(("fish", "chinese")):
    for col, (kind, label) in enumerate(kinds):
        ax = axes[row, col]
        lv = [k for k in names if k.startswith(f"{shape}_{kind}_")]
        x = [int(k.rsplit("_", 1)[1]) for k in lv]
        for m in used:
            ax.plot(x, [mean_err[m][k] for k in lv], "o-" if m == "shapelib" else "s--", label=LABELS[m], ms=4,
                    lw=2 if m == "shapelib" else 1)
        ax.set_title(f"{shape}: {label}", fontsize=9)
        ax.set_xlabel("level")
        ax.set_yscale("symlog", linthresh=1e-3)
    axes[row, 0].set_ylabel("mean error")
axes[0, 0].legend(fontsize=8)
fig.tight_layout()
save_figure(fig, output_dir, "pointset_registration_levels")

# %% [markdown]
# ## One example of each degradation
#
# The hardest level of each degradation that ran (sample 1): the target (grey), the best peer's
# result at that level (blue) and shapelib's (red), template points with a ground truth joined to
# their true positions.

# %%
examples = []
for kind, label in kinds:
    lv = [k for k in names if k.startswith(f"fish_{kind}_")] or [k for k in names if f"_{kind}_" in k]
    if lv:
        examples.append((lv[-1], label))
if examples:
    fig, axes = plt.subplots(2, len(examples), figsize=(3.2 * len(examples), 6.2), squeeze=False)
    for col, (name, label) in enumerate(examples):
        case = load_tps_rpm_case(name, sample=1)
        n = len(case["y2"])
        others = [m for m in used if m != "shapelib"]
        shown = ([min(others, key=lambda m: mean_err[m][name])] if others else []) + (["shapelib"] if "shapelib" in used else [])
        for row, m in enumerate(shown):
            ax = axes[row, col]
            ax.plot(*case["y2a"].T, ".", color="0.6", ms=3)
            p = moved[(m, name)]
            ax.plot(*p.T, ".", color="tab:red" if m == "shapelib" else "tab:blue", ms=3)
            for a, b in zip(p[:n], case["y2"]):
                ax.plot([a[0], b[0]], [a[1], b[1]], "-", color="k", lw=0.4)
            ax.set_title(f"{LABELS[m]}, {name.replace('_', ' ')}: {mean_err[m][name]:.3f}", fontsize=8)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    save_figure(fig, output_dir, "pointset_registration_examples")

# %% [markdown]
# ## Summary

# %%
peers = [m for m in used if m != "shapelib"]
best = {k: min(mean_err[p][k] for p in peers) for k in names} if peers else {}
below = [k for k in names if "shapelib" in used and peers and mean_err["shapelib"][k] <= best[k]]
summary = {"registration/summary/levels": len(names), "registration/summary/shapelib_le_every_peer": len(below)}
for m in LABELS:  # every method's entries, NaN for one that did not run
    summary[f"registration/summary/{m}_mean_error"] = float(np.mean(list(mean_err[m].values()))) if m in used else float("nan")
    summary[f"registration/summary/{m}_failures"] = int(sum(failures[m].values())) if m in used else -1
    summary[f"registration/summary/{m}_median_seconds"] = float(np.median(times[m])) if m in used else float("nan")
values = dict(summary)
for m in mean_err:
    values.update({f"registration/{m}/{k}": v for k, v in mean_err[m].items()})
record_values(output_dir, values, notes={
    "registration": "Chui–Rangarajan benchmark: mean |moved − truth| over the template points with a ground truth; "
                    f"{samples} sample(s) per level; shapelib.register with its defaults beside "
                    f"{', '.join(LABELS[p] for p in peers)} (each its defaults, MATLAB-CPD normalisation; FilterReg and "
                    "GMMTree rigid only, given the 2-D sets with z = 0), BLAS on one thread; a failure is an error "
                    "> 0.05 or a raised exception; failures -1 and NaN: the method did not run."})
not_below = [k for k in names if k not in below]
# per degradation × shape: every method's mean error and failures over the family's levels
kinds_run = [(shape, kind, label) for shape in ("fish", "chinese") for kind, label in kinds
             if any(k.startswith(f"{shape}_{kind}_") for k in names)]
fam_rows = []
for shape, kind, label in kinds_run:
    lv = [k for k in names if k.startswith(f"{shape}_{kind}_")]
    cells = [f"{np.mean([mean_err[m][k] for k in lv]):.4f} ({sum(failures[m][k] for k in lv)})" for m in used]
    fam_rows.append(f"| {shape}: {label} | " + " | ".join(cells) + " |")
header = "| " + " | ".join(LABELS[m] for m in used) + " |"
# the study report's section (run_all.py gathers it under "Beyond the paper")
rows = "\n".join(f"| {k.replace('_', ' ')} | " + " | ".join(f"{mean_err[m][k]:.4f} ({failures[m][k]})" for m in used)
                 + f" | {'yes' if k in below else 'no'} |" for k in names)
med = ", ".join(f"{LABELS[m]} {1000 * np.median(times[m]):.0f} ms" for m in used)
section = "\n".join([
    f"Chui–Rangarajan benchmark, {len(names)} levels, {samples} sample(s) per level: mean |moved − truth| over the "
    f"template points with a ground truth (in brackets the registrations with error > 0.05 or a raised exception), "
    f"shapelib.register with its defaults beside {', '.join(LABELS[p] for p in peers)}, each with its defaults, "
    f"the same inputs in the same run (FilterReg and GMMTree are rigid only and take 3-D points: the planar sets are "
    f"given to them with z = 0). shapelib is at or below every peer at {len(below)} of {len(names)} levels; "
    f"not at: {', '.join(k.replace('_', ' ') for k in not_below) or 'none'}. Median time per registration: {med}.",
    "",
    "| degradation" + header, "|---" * (len(used) + 1) + "|", *fam_rows,
    "",
    "| level" + header + " shapelib ≤ every peer |",
    "|---" * (len(used) + 2) + "|",
    rows,
    "",
    "![errors per level](pointset_registration/pointset_registration_levels.png)",
])
(Path(output_dir) / "report_section.md").write_text(section + "\n")
print(f"shapelib at or below every peer at {len(below)} of {len(names)} levels; not at: {', '.join(not_below) or 'none'}")
print(f"median time per registration: {med}")
