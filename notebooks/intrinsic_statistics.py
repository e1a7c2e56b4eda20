# %% [markdown]
# # Beyond the paper — shapes out: mean shapes, modes, age trends and group differences
#
# `adhd200_population` tells how far apart the ADHD-200 corpus callosum shapes are and finds "a
# small diagnosis effect". This notebook answers with shapes, in the information geometry of the
# paper: the **Fréchet mean** of typically developing (TD) and ADHD subjects under the α-order
# metric (and Fisher–Rao on a balanced subset), their difference as a magnified deformation
# drawn by the paper's own extrinsic warp (§III-E) with a permutation p-value, the principal
# **modes of variation** at the mean (tangent PCA, orthonormal in the metric) with the
# diagnosis groups in mode space, and shape against **age** by geodesic regression. Each answer
# stands beside the Procrustes one (GPA mean, PCA of Procrustes tangent coordinates, linear
# regression). A second data set, the mosquito wings that ktch ships, shows the same tools on
# anatomical landmarks: genus means and modes. Every sentence with a number is generated from
# the computed values (`shapelib.statistics`).

# %% tags=["parameters"]
from shapelib.study import default_output_dir
output_dir = default_output_dir("intrinsic_statistics")  # run_all.py passes its own
n_shapes = 647  # ADHD-200 shapes analysed (a stratified sample when < 647)
n_subset = 180  # the balanced subset (diagnosis x sex) for the Fisher–Rao means
sigma_ratio = 2.6  # σ in landmark spacings at centroid size 20 (σ² 1.2), as in adhd200_population
n_steps = 4  # segments of the discrete geodesics behind every log map
tol = 1e-3  # first-order certificate of the means: |mean of the logs| / their spread
fisher_rao = True
fisher_rao_n_steps = 4
fisher_rao_grid_spacing = 0.5  # Fisher–Rao quadrature step in units of σ (library default 0.35)
permutations = 999
geodesic_steps = 16  # segments of the geodesics between means (and of the pictures drawn along them)
magnification = 3.0  # of the deformation pictures, as geomorph's plotRefToTarget mag
ages = [8.0, 20.0]  # where the age trend is drawn
wings_min_genus = 10  # genera of the mosquito wings with at least this many specimens
seed = 0
n_jobs = None  # None: a local Dask cluster of one worker per core for the larger populations; 1: this process

# %%
import time
import warnings

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

import shapelib as sl
from shapelib import plotting
from shapelib.datasets import load_adhd200
from shapelib.geometry.procrustes import procrustes_distance
from shapelib.study import PAPER_CENTROID_SIZE, record_values, save_figure, stratified_sample

values, notes, timings = {}, {}, {}
raw, clinical = load_adhd200()
labels = pd.DataFrame({
    "diagnosis": np.where(clinical["phenotype"].to_numpy() == 0, "TD", "ADHD"),
    "sex": clinical["gender"].astype(int).astype(str).to_numpy(),
    "age": clinical["age"].to_numpy(dtype=np.float64),
})


#: the diagnosis × sex cells every subsample is balanced over
cells = [(labels.diagnosis.to_numpy() == d) & (labels.sex.to_numpy() == s) for d in ("TD", "ADHD") for s in ("0", "1")]


def stratified(idx, n, rng):
    """``n`` of ``idx`` balanced over the diagnosis × sex cells (all of them if n >= len(idx))."""
    return stratified_sample(idx, n, cells, rng)


rng = np.random.default_rng(seed)
sel = stratified(np.arange(len(raw)), int(n_shapes), rng)
shapes = sl.to_centroid_size(raw[sel])  # GPA (rotations) and centroid size 20, as adhd200_population
lab = labels.iloc[sel].reset_index(drop=True)
spacing = sl.landmark_spacing(shapes)
sigma2 = float(f"{(sigma_ratio * spacing) ** 2:.2g}")
is_adhd = lab.diagnosis.to_numpy() == "ADHD"
print(len(shapes), "shapes;", int(is_adhd.sum()), "ADHD;", f"σ² = {sigma2:g}")

# %% [markdown]
# ## Where the log maps run
#
# Every statistic here is built from log maps (one path solve per shape per iteration). With
# `n_jobs=None` a population of 100 shapes or more runs on a local Dask cluster of one worker per
# core, started once and handed to every call as `client=` (`shapelib.pairwise.local_cluster`);
# smaller ones run in this process.

# %%
client = cluster = None
if n_jobs != 1 and len(shapes) >= 100:
    from distributed import Client

    from shapelib.pairwise import local_cluster

    cluster = local_cluster(n_jobs or len(__import__("os").sched_getaffinity(0)))
    client = Client(cluster)
where = {"client": client} if client is not None else {"n_jobs": 1}
print("log maps:", "Dask cluster" if client is not None else "this process")


def timed(name, fn, *args, **kw):
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sl.ScaleWarning)
        out = fn(*args, **kw)
    timings[name] = time.perf_counter() - t0
    return out


# %% [markdown]
# ## The mean shapes of TD and ADHD subjects, and their difference
#
# The pooled Fréchet mean (Karcher iteration from the Procrustes mean, to a first-order certificate
# |mean of the log maps| / spread ≤ `tol`), the two groups' Fréchet means (started from it), the
# geodesic between them and a permutation test of the difference (the metric distance of the
# groups' mean log maps at the pooled mean; exact under exchangeable labels). Beside it the
# Procrustes answer: GPA means of the aligned shapes and the same permutation test on their
# coordinates (Euclidean norm of the difference of the group means).

# %%
alpha_test = timed("alpha_means", sl.mean_difference_test, shapes, lab.diagnosis.to_numpy(), metric="alpha",
                   sigma2=sigma2, order=("TD", "ADHD"), n_permutations=permutations, seed=seed, tol=tol,
                   n_steps=n_steps, geodesic_steps=geodesic_steps, **where)
pooled = alpha_test.pooled
print(pooled.summary())
print(alpha_test.summary())
for g, m in zip(alpha_test.labels, alpha_test.means):
    print(g, m.summary())


def procrustes_test(x, is_b, n_perm, rng):
    """Permutation test of ‖mean_B − mean_A‖ on aligned coordinates: the Procrustes counterpart."""
    flat = x.reshape(len(x), -1)
    obs = np.linalg.norm(flat[is_b].mean(0) - flat[~is_b].mean(0))
    null = np.array([np.linalg.norm(flat[p].mean(0) - flat[~p].mean(0))
                     for p in (rng.permutation(is_b) for _ in range(n_perm))])
    return obs, (1 + np.count_nonzero(null >= obs * (1 - 1e-12))) / (1 + n_perm)


gpa_td, gpa_adhd = shapes[~is_adhd].mean(0), shapes[is_adhd].mean(0)
proc_stat, proc_p = procrustes_test(shapes, is_adhd, permutations, np.random.default_rng(seed))
proc_dist = procrustes_distance(gpa_td, gpa_adhd)  # Kendall's shape-space angle between the GPA means
# how much of each analysis' variance the diagnosis explains (between-group share)
n_td, n_adhd = int((~is_adhd).sum()), int(is_adhd.sum())
share_alpha = n_td * n_adhd / len(shapes) ** 2 * alpha_test.statistic ** 2 / pooled.spread ** 2
flat = shapes.reshape(len(shapes), -1)
share_proc = n_td * n_adhd / len(shapes) ** 2 * proc_stat ** 2 / np.mean(np.sum((flat - flat.mean(0)) ** 2, axis=1))
# do the two answers point the same way? the mean differences as landmark displacements
d_alpha = alpha_test.means[1].mean - alpha_test.means[0].mean
d_proc = gpa_adhd - gpa_td
cos_eucl = float(np.sum(d_alpha * d_proc) / np.linalg.norm(d_alpha) / np.linalg.norm(d_proc))
ts = pooled.tangent
cos_metric = float(ts.inner(d_alpha, d_proc) / ts.norm(d_alpha) / ts.norm(d_proc))
values.update({
    "intrinsic/adhd/alpha/variance": pooled.variance,
    "intrinsic/adhd/alpha/certificate": pooled.certificate,
    "intrinsic/adhd/alpha/iterations": pooled.n_iter,
    "intrinsic/adhd/alpha/rank": ts.rank,
    "intrinsic/adhd/alpha/discarded_fraction": pooled.discarded_fraction,
    "intrinsic/adhd/alpha/statistic": alpha_test.statistic,
    "intrinsic/adhd/alpha/p": alpha_test.p_value,
    "intrinsic/adhd/alpha/distance": alpha_test.distance,
    "intrinsic/adhd/alpha/distance_lower": alpha_test.geodesic.lower_bound,
    "intrinsic/adhd/alpha/diagnosis_share": share_alpha,
    "intrinsic/adhd/procrustes/statistic": proc_stat,
    "intrinsic/adhd/procrustes/p": proc_p,
    "intrinsic/adhd/procrustes/angle": proc_dist,
    "intrinsic/adhd/procrustes/diagnosis_share": share_proc,
    "intrinsic/adhd/procrustes/cos_euclidean": cos_eucl,
    "intrinsic/adhd/procrustes/cos_metric": cos_metric,
})
print(f"Procrustes: |mean_ADHD - mean_TD| = {proc_stat:.4g}, p = {proc_p:.4g}; cos(α, Procrustes difference) = "
      f"{cos_eucl:.3f} (coordinates), {cos_metric:.3f} (α metric)")

# %%
fig = plotting.plot_mean_difference(alpha_test, mag=magnification, every=4)
save_figure(fig, output_dir, "alpha_td_adhd_means")
plt.show()

# where the two differences move the contour: displacement per landmark, α against Procrustes. The α
# difference of the landmark representatives also holds slides along the contour that change no
# density (the weak directions of the metric); drawn is its part in the directions of g(pooled mean)
# above 1e-3 of the largest eigenvalue, which carries all but the recorded share of its metric norm.
keep = ts.eigenvalues > 1e-3 * ts.eigenvalues[0]
basis = ts.eigenvectors[:, keep]
d_alpha_seen = (basis @ (basis.T @ d_alpha.ravel())).reshape(d_alpha.shape)
values["intrinsic/adhd/alpha/difference_weak_share"] = float(1 - ts.inner(d_alpha_seen, d_alpha_seen)
                                                             / ts.inner(d_alpha, d_alpha))
print(f"share of the α difference's squared metric norm in the weak directions: "
      f"{values['intrinsic/adhd/alpha/difference_weak_share']:.1e}")
fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), layout="constrained")
for ax, (name, base, diff) in zip(axes, [("α Fréchet means", alpha_test.means[0].mean, d_alpha_seen),
                                         ("GPA means", gpa_td, d_proc)]):
    ax.plot(*plotting.outline(base).T, "-", color="0.6", lw=0.8)
    ax.plot(*plotting.outline(base + magnification * 10 * diff).T, "-", color="k", lw=1.2)
    ax.quiver(base[:, 0], base[:, 1], diff[:, 0], diff[:, 1], angles="xy", scale_units="xy",
              scale=1 / (magnification * 10), width=0.003)
    ax.set_aspect("equal")
    ax.set_title(f"TD → ADHD, {name} (×{magnification * 10:g})", fontsize=9)
save_figure(fig, output_dir, "td_adhd_displacements")
plt.show()

# %% [markdown]
# ## Fisher–Rao on the balanced subset
#
# Fisher–Rao log maps cost a quadrature per evaluation (about 20× an α one); we compute them on
# the subset balanced over diagnosis × sex that `adhd200_population` uses for its geodesic
# distances (the same subjects, drawn with the same seed), with α and Procrustes on the same
# subset for comparison.

# %%
sub = np.searchsorted(sel, stratified(sel, int(n_subset), rng))  # adhd200_population's geodesic subset (same draws)
sub_x, sub_lab = shapes[sub], lab.diagnosis.to_numpy()[sub]
sub_where = where if len(sub) >= 100 else {"n_jobs": 1}
sub_alpha = timed("alpha_subset", sl.mean_difference_test, sub_x, sub_lab, metric="alpha", sigma2=sigma2,
                  order=("TD", "ADHD"), n_permutations=permutations, seed=seed, tol=tol, n_steps=n_steps,
                  geodesic_steps=geodesic_steps, **sub_where)
values.update({"intrinsic/adhd/subset/alpha/p": sub_alpha.p_value,
               "intrinsic/adhd/subset/alpha/distance": sub_alpha.distance})
sub_proc_stat, sub_proc_p = procrustes_test(sub_x, sub_lab == "ADHD", permutations, np.random.default_rng(seed))
values["intrinsic/adhd/subset/procrustes/p"] = sub_proc_p
print(sub_alpha.summary())
if fisher_rao:
    fr_test = timed("fisher_rao_means", sl.mean_difference_test, sub_x, sub_lab, metric="fisher_rao", sigma2=sigma2,
                    order=("TD", "ADHD"), n_permutations=permutations, seed=seed, tol=tol, n_steps=fisher_rao_n_steps,
                    grid_spacing=fisher_rao_grid_spacing, geodesic_steps=geodesic_steps, **sub_where)
    fr_pooled = fr_test.pooled
    print(fr_pooled.summary())
    print(fr_test.summary())
    d_fr = fr_test.means[1].mean - fr_test.means[0].mean
    d_sub = sub_alpha.means[1].mean - sub_alpha.means[0].mean
    cos_fr = float(np.sum(d_fr * d_sub) / np.linalg.norm(d_fr) / np.linalg.norm(d_sub))
    values.update({
        "intrinsic/adhd/fisher_rao/variance": fr_pooled.variance,
        "intrinsic/adhd/fisher_rao/certificate": fr_pooled.certificate,
        "intrinsic/adhd/fisher_rao/iterations": fr_pooled.n_iter,
        "intrinsic/adhd/fisher_rao/p": fr_test.p_value,
        "intrinsic/adhd/fisher_rao/distance": fr_test.distance,
        "intrinsic/adhd/fisher_rao/cos_alpha": cos_fr,
        "intrinsic/adhd/fisher_rao/mean_gap_l2": float(sl.l2_distance(fr_pooled.mean, sub_alpha.pooled.mean, sigma2=sigma2)
                                                      / np.sqrt(sub_alpha.pooled.variance)),
    })
    fig = plotting.plot_mean_difference(fr_test, mag=magnification, every=4)
    save_figure(fig, output_dir, "fisher_rao_td_adhd_means")
    plt.show()

# %% [markdown]
# ## Modes of variation and the diagnosis groups in mode space
#
# Tangent PCA at the pooled α Fréchet mean: components orthonormal in the metric g(mean), shapes
# at ±2 SD by the exponential map. Beside it ordinary PCA of the Procrustes tangent coordinates
# (the aligned shapes minus their mean).

# %%
pca = timed("tangent_pca", sl.tangent_pca, shapes, mean=pooled, modes=(0, 1, 2), sd=(-2.0, 0.0, 2.0))
print(pca.summary())
from sklearn.decomposition import PCA

ppca = PCA().fit(flat)
proc_scores = ppca.transform(flat)
k = 5
# a component's sign is arbitrary: orient each Procrustes component like the α one it matches
signs = np.sign([np.corrcoef(pca.scores[:, j], proc_scores[:, j])[0, 1] for j in range(k)])
proc_scores[:, :k] *= signs
ppca.components_[:k] *= signs[:, None]
corr = [abs(np.corrcoef(pca.scores[:, j], proc_scores[:, j])[0, 1]) for j in range(3)]
for j in range(k):
    values[f"intrinsic/adhd/pca/alpha_ratio_{j + 1}"] = float(pca.explained_variance_ratio[j])
    values[f"intrinsic/adhd/pca/procrustes_ratio_{j + 1}"] = float(ppca.explained_variance_ratio_[j])
for j in range(3):
    values[f"intrinsic/adhd/pca/score_corr_{j + 1}"] = float(corr[j])


def group_shift(scores, is_b, n_perm, rng):
    """Mean score difference (B − A) per component in SD units, with permutation p-values."""
    sd = scores.std(axis=0, ddof=1)
    obs = (scores[is_b].mean(0) - scores[~is_b].mean(0)) / sd
    null = np.array([(scores[p].mean(0) - scores[~p].mean(0)) / sd
                     for p in (rng.permutation(is_b) for _ in range(n_perm))])
    return obs, (1 + np.sum(np.abs(null) >= np.abs(obs) * (1 - 1e-12), axis=0)) / (1 + n_perm)


shift_a, p_a = group_shift(pca.scores[:, :3], is_adhd, permutations, np.random.default_rng(seed))
shift_p, p_p = group_shift(proc_scores[:, :3], is_adhd, permutations, np.random.default_rng(seed))
for j in range(3):
    values[f"intrinsic/adhd/pca/alpha_shift_{j + 1}"] = float(shift_a[j])
    values[f"intrinsic/adhd/pca/alpha_shift_p_{j + 1}"] = float(p_a[j])
    values[f"intrinsic/adhd/pca/procrustes_shift_{j + 1}"] = float(shift_p[j])
    values[f"intrinsic/adhd/pca/procrustes_shift_p_{j + 1}"] = float(p_p[j])
pd.DataFrame({"α ratio": pca.explained_variance_ratio[:k], "Procrustes ratio": ppca.explained_variance_ratio_[:k]},
             index=[f"PC{j + 1}" for j in range(k)])

# %%
fig = plotting.plot_modes(pca, components=(0, 1, 2), sd=(-2.0, 0.0, 2.0))
save_figure(fig, output_dir, "alpha_modes")
plt.show()
fig, axes = plt.subplots(3, 3, figsize=(7.8, 7.8), layout="constrained")
mean_p = flat.mean(0)
for r in range(3):
    for c, s in enumerate((-2.0, 0.0, 2.0)):
        ax = axes[r, c]
        shape = (mean_p + s * np.sqrt(ppca.explained_variance_[r]) * ppca.components_[r]).reshape(-1, 2)
        ax.plot(*plotting.outline(mean_p.reshape(-1, 2)).T, "--", color="0.6", lw=0.8)
        ax.plot(*plotting.outline(shape).T, "-o", color="k", lw=1.2, ms=2)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"Procrustes PC{r + 1} ({100 * ppca.explained_variance_ratio_[r]:.1f} %), {s:+g} SD", fontsize=8)
save_figure(fig, output_dir, "procrustes_modes")
plt.show()
fig, axes = plt.subplots(1, 2, figsize=(9, 4), layout="constrained")
for ax, sc, name in ((axes[0], pca.scores, "α tangent PCA"), (axes[1], proc_scores, "Procrustes PCA")):
    for g, colour in (("TD", "tab:blue"), ("ADHD", "tab:orange")):
        m = lab.diagnosis.to_numpy() == g
        ax.scatter(sc[m, 0], sc[m, 1], s=6, alpha=0.5, color=colour, label=g)
        ax.plot(*sc[m, :2].mean(0), "X", color=colour, ms=11, mec="k")
    ax.set_xlabel("PC1")
    ax.set_ylabel("PC2")
    ax.set_title(name, fontsize=9)
    ax.legend(fontsize=8)
save_figure(fig, output_dir, "diagnosis_in_mode_space")
plt.show()

# %% [markdown]
# ## Shape against age
#
# Geodesic regression under α (the geodesic γ(t) that minimises Σ d²(yᵢ, γ(ageᵢ)), Fletcher's
# R² against the Fréchet mean), and linear regression of the aligned coordinates on age (R² of
# the sums of squares). Predicted shapes at 8 and 20 years.

# %%
reg = timed("regression", sl.geodesic_regression, shapes, lab.age.to_numpy(), metric="alpha", sigma2=sigma2,
            mean=pooled, tol=tol, n_steps=n_steps, **where)
print(reg.summary())
age = lab.age.to_numpy()
tc = age - age.mean()
slope = np.einsum("n,nkd->kd", tc, shapes) / (tc @ tc)
fit_lin = shapes.mean(0) + tc[:, None, None] * slope
r2_lin = 1 - np.sum((shapes - fit_lin) ** 2) / np.sum((shapes - shapes.mean(0)) ** 2)


def linear_r2(t):
    c = t - t.mean()
    b = np.einsum("n,nkd->kd", c, shapes) / (c @ c)
    return 1 - np.sum((shapes - shapes.mean(0) - c[:, None, None] * b) ** 2) / np.sum((shapes - shapes.mean(0)) ** 2)


perm_rng = np.random.default_rng(seed)
null_r2 = np.array([linear_r2(perm_rng.permutation(age)) for _ in range(permutations)])
p_lin = (1 + np.count_nonzero(null_r2 >= r2_lin * (1 - 1e-12))) / (1 + permutations)
pred_alpha = reg.predict(ages)
pred_lin = shapes.mean(0) + (np.asarray(ages) - age.mean())[:, None, None] * slope
trend_alpha, trend_lin = pred_alpha[1] - pred_alpha[0], pred_lin[1] - pred_lin[0]
cos_age = float(np.sum(trend_alpha * trend_lin) / np.linalg.norm(trend_alpha) / np.linalg.norm(trend_lin))
values.update({
    "intrinsic/adhd/regression/alpha_r2": reg.r2,
    "intrinsic/adhd/regression/alpha_certificate": reg.certificate,
    "intrinsic/adhd/regression/alpha_speed": reg.speed,
    "intrinsic/adhd/regression/linear_r2": float(r2_lin),
    "intrinsic/adhd/regression/linear_p": float(p_lin),
    "intrinsic/adhd/regression/linear_null_r2": float(null_r2.mean()),
    "intrinsic/adhd/regression/cos_trend": cos_age,
    "intrinsic/adhd/regression/alpha_distance_8_20": float(sl.path_length(
        sl.geodesic(pred_alpha[0], pred_alpha[1], sigma2=sigma2, n_steps=8).path, sigma2=sigma2)),
})
a_lo, a_hi = ages
fig, axes = plt.subplots(1, 3, figsize=(12, 3.8), layout="constrained")
for ax, (name, pr) in zip(axes[:2], (("α geodesic regression", pred_alpha), ("linear regression (Procrustes)", pred_lin))):
    ax.plot(*plotting.outline(pr[0]).T, "-", color="tab:blue", lw=1.2, label=f"{a_lo:g} years")
    ax.plot(*plotting.outline(pr[1]).T, "-", color="tab:red", lw=1.2, label=f"{a_hi:g} years")
    ax.set_aspect("equal")
    ax.legend(fontsize=8)
    ax.set_title(name, fontsize=9)
age_geo = sl.geodesic(pred_alpha[0], pred_alpha[1], sigma2=sigma2, n_steps=geodesic_steps)
plotting.plot_deformation(axes[2], age_geo, mag=magnification)
axes[2].set_title(f"{a_lo:g} → {a_hi:g} years (α), magnified {magnification:g}×", fontsize=9)
save_figure(fig, output_dir, "age_trend")
plt.show()

# %% [markdown]
# ## A second data set: mosquito wings (ktch)
#
# 127 wings, 18 anatomical landmarks, 11 genera (ktch's `load_landmark_mosquito_wings`). Genera with
# at least `wings_min_genus` specimens; the same scale (centroid size 20) and σ² as above, which at
# these sparse landmarks puts σ near one landmark spacing.

# %%
from ktch.datasets import load_landmark_mosquito_wings

bunch = load_landmark_mosquito_wings(as_frame=True)
genus_all = bunch.meta["genus"].astype(str).to_numpy()
wings_all = bunch.coords.to_numpy().reshape(len(genus_all), -1, 2)
counts = pd.Series(genus_all).value_counts()
keep_genera = [g for g in counts.index if counts[g] >= wings_min_genus]
keep = np.isin(genus_all, keep_genera)
wings = sl.to_centroid_size(wings_all[keep])
genus = genus_all[keep]
wings_where = where if len(wings) >= 100 else {"n_jobs": 1}
w_pooled = timed("wings_mean", sl.frechet_mean, wings, metric="alpha", sigma2=sigma2, tol=tol, n_steps=n_steps,
                 **wings_where)
w_pca = sl.tangent_pca(wings, mean=w_pooled, modes=(0, 1), sd=(-2.0, 0.0, 2.0))
print(w_pooled.summary())
print(w_pca.summary())
from shapelib.statistics.frechet import karcher_iteration

genus_means = {}
for g in keep_genera:
    m = genus == g
    genus_means[g] = karcher_iteration(wings[m], w_pooled.mean, options=w_pooled.options, tol=tol, max_iter=30,
                                       inits=[p for p, s in zip(w_pooled.paths, m) if s])
w_ppca = PCA().fit(wings.reshape(len(wings), -1))
values.update({"intrinsic/wings/n_specimens": len(wings), "intrinsic/wings/n_genera": len(keep_genera),
               "intrinsic/wings/sigma_over_spacing": float(np.sqrt(sigma2) / sl.landmark_spacing(wings)),
               "intrinsic/wings/certificate": w_pooled.certificate})
for j in range(2):
    values[f"intrinsic/wings/alpha_ratio_{j + 1}"] = float(w_pca.explained_variance_ratio[j])
    values[f"intrinsic/wings/procrustes_ratio_{j + 1}"] = float(w_ppca.explained_variance_ratio_[j])
# distances between the genus means: α geodesic length against the Procrustes angle between GPA means
rows = []
for i, a in enumerate(keep_genera):
    for b in keep_genera[i + 1:]:
        geo = sl.geodesic(genus_means[a].mean, genus_means[b].mean, sigma2=sigma2, n_steps=8)
        rows.append({"a": a, "b": b, "alpha": geo.length,
                     "procrustes": procrustes_distance(wings[genus == a].mean(0), wings[genus == b].mean(0))})
genus_table = pd.DataFrame(rows)
from scipy.stats import spearmanr

rho = spearmanr(genus_table.alpha, genus_table.procrustes).statistic if len(genus_table) > 2 else float("nan")
if np.isfinite(rho):
    values["intrinsic/wings/genus_distance_spearman"] = float(rho)
big2 = keep_genera[:2]
m2 = np.isin(genus, big2)
w_test = sl.mean_difference_test(wings[m2], genus[m2], sigma2=sigma2, order=tuple(big2), n_permutations=permutations,
                                 seed=seed, tol=tol, n_steps=n_steps, geodesic_steps=geodesic_steps, n_jobs=1)
values.update({"intrinsic/wings/test_p": w_test.p_value, "intrinsic/wings/test_distance": w_test.distance})
print(genus_table)
print(w_test.summary())

# %%
fig, axes = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
for g in keep_genera:
    m = genus == g
    axes[0].plot(*genus_means[g].mean.T, "o", ms=4, label=f"{g} (n = {m.sum()})")
    axes[1].scatter(w_pca.scores[m, 0], w_pca.scores[m, 1], s=10, label=g)
axes[0].set_aspect("equal")
axes[0].legend(fontsize=8)
axes[0].set_title("α Fréchet mean of each genus", fontsize=9)
axes[1].set_xlabel(f"PC1 ({100 * w_pca.explained_variance_ratio[0]:.1f} %)")
axes[1].set_ylabel(f"PC2 ({100 * w_pca.explained_variance_ratio[1]:.1f} %)")
axes[1].legend(fontsize=8)
axes[1].set_title("genera in α mode space", fontsize=9)
save_figure(fig, output_dir, "wings_genus_means")
plt.show()
fig = plotting.plot_modes(w_pca, components=(0, 1), sd=(-2.0, 0.0, 2.0), closed=None)
save_figure(fig, output_dir, "wings_modes")
plt.show()
fig = plotting.plot_mean_difference(w_test, mag=magnification, closed=None, every=2)
save_figure(fig, output_dir, "wings_genus_difference")
plt.show()

# %%
if client is not None:
    client.close()
    cluster.close()

# %% [markdown]
# ## What agrees and what differs

# %%
v = values
sig = lambda p: "differ" if p <= 0.05 else "do not differ detectably"  # noqa: E731
way = lambda c: ("point the same way" if c >= 0.8 else "point roughly the same way" if c >= 0.5  # noqa: E731
                 else "point different ways")
fr_text = ""
if fisher_rao:
    fr_text = (
        f" On the subset of {len(sub)} subjects balanced over diagnosis × sex that adhd200_population uses for its "
        f"geodesic distances, the TD–ADHD permutation p is {v['intrinsic/adhd/fisher_rao/p']:.3g} under Fisher–Rao, "
        f"{v['intrinsic/adhd/subset/alpha/p']:.3g} under α and {v['intrinsic/adhd/subset/procrustes/p']:.3g} under "
        f"Procrustes (a pure two-group test; adhd200_population's PERMANOVA also models sex and age); the Fisher–Rao "
        f"and α mean differences {way(v['intrinsic/adhd/fisher_rao/cos_alpha'])} (cosine {v['intrinsic/adhd/fisher_rao/cos_alpha']:.2f} between "
        f"the landmark displacements), and the Fisher–Rao and α pooled means differ by "
        f"{v['intrinsic/adhd/fisher_rao/mean_gap_l2']:.2g} of the α spread in L² density distance.")
lines = [
    "### Mean shapes, modes and age trends in the information geometry (`intrinsic_statistics`)", "",
    f"On {len(shapes)} ADHD-200 contours ({n_td} TD, {n_adhd} ADHD) at σ² = {sigma2:g} (centroid size "
    f"{PAPER_CENTROID_SIZE:g}) the α Fréchet mean converged to a certificate of {v['intrinsic/adhd/alpha/certificate']:.1e} "
    f"in {v['intrinsic/adhd/alpha/iterations']:.0f} Karcher iteration(s) from the Procrustes mean; the metric at the mean "
    f"keeps {v['intrinsic/adhd/alpha/rank']:.0f} of {shapes[0].size} directions (the rest are landmarks sliding along the "
    f"contour, which hold {v['intrinsic/adhd/alpha/discarded_fraction']:.1e} of the variance). "
    f"**The TD and ADHD mean shapes {sig(v['intrinsic/adhd/alpha/p'])}**: α geodesic distance "
    f"{v['intrinsic/adhd/alpha/distance']:.3g} between the groups' Fréchet means "
    f"(tangent statistic {v['intrinsic/adhd/alpha/statistic']:.3g}; permutation p = {v['intrinsic/adhd/alpha/p']:.3g}, "
    f"{permutations} permutations), against a root-mean-square distance of {np.sqrt(v['intrinsic/adhd/alpha/variance']):.3g} "
    f"of a subject from the mean: diagnosis accounts for {100 * v['intrinsic/adhd/alpha/diagnosis_share']:.2f} % of the α "
    f"variance ({100 * v['intrinsic/adhd/procrustes/diagnosis_share']:.2f} % of the Procrustes variance, p = "
    f"{v['intrinsic/adhd/procrustes/p']:.3g}). The two answers {way(v['intrinsic/adhd/procrustes/cos_euclidean'])}: the cosine between the α and the "
    f"Procrustes mean differences is {v['intrinsic/adhd/procrustes/cos_euclidean']:.2f} in landmark coordinates and "
    f"{v['intrinsic/adhd/procrustes/cos_metric']:.2f} in the α metric (which discounts sliding along the contour)." + fr_text,
    "",
    f"**Modes.** The first α modes explain {100 * v['intrinsic/adhd/pca/alpha_ratio_1']:.1f} %, "
    f"{100 * v['intrinsic/adhd/pca/alpha_ratio_2']:.1f} % and {100 * v['intrinsic/adhd/pca/alpha_ratio_3']:.1f} % of the "
    f"tangent variance (Procrustes PCA: {100 * v['intrinsic/adhd/pca/procrustes_ratio_1']:.1f} %, "
    f"{100 * v['intrinsic/adhd/pca/procrustes_ratio_2']:.1f} %, {100 * v['intrinsic/adhd/pca/procrustes_ratio_3']:.1f} %); "
    f"the scores of the two analyses' first three modes correlate at |r| = "
    + ", ".join(f"{v[f'intrinsic/adhd/pca/score_corr_{j}']:.2f}" for j in (1, 2, 3))
    + " (each Procrustes component oriented like the α one). ADHD subjects sit "
    + ", ".join(f"{v[f'intrinsic/adhd/pca/alpha_shift_{j}']:+.2f} SD on α PC{j} (p = {v[f'intrinsic/adhd/pca/alpha_shift_p_{j}']:.3g})"
                for j in (1, 2, 3))
    + " from TD subjects (Procrustes: "
    + ", ".join(f"{v[f'intrinsic/adhd/pca/procrustes_shift_{j}']:+.2f} SD, p = {v[f'intrinsic/adhd/pca/procrustes_shift_p_{j}']:.3g}"
                for j in (1, 2, 3)) + ").",
    "",
    f"**Age.** Geodesic regression on age gives Fletcher's R² = {v['intrinsic/adhd/regression/alpha_r2']:.4f} and "
    f"linear regression of the Procrustes coordinates R² = {v['intrinsic/adhd/regression/linear_r2']:.4f} "
    f"(permutation p = {v['intrinsic/adhd/regression/linear_p']:.3g}; shuffled ages give R² = "
    f"{v['intrinsic/adhd/regression/linear_null_r2']:.4f} on average)"
    + (": shape does not change detectably with age between "
       f"{age.min():.0f} and {age.max():.0f} years in this population. " if v['intrinsic/adhd/regression/linear_p'] > 0.05
       else ". ")
    + f"The predicted shapes at {a_lo:g} and {a_hi:g} years are {v['intrinsic/adhd/regression/alpha_distance_8_20']:.3g} "
    f"apart under α ({v['intrinsic/adhd/regression/alpha_distance_8_20'] / np.sqrt(v['intrinsic/adhd/alpha/variance']):.2f} "
    f"of the root-mean-square distance from the mean); the α and linear age trends {way(v['intrinsic/adhd/regression/cos_trend'])} (cosine "
    f"{v['intrinsic/adhd/regression/cos_trend']:.2f} between the predicted {a_lo:g}→{a_hi:g} displacements).",
    "",
    f"**Mosquito wings.** {v['intrinsic/wings/n_specimens']:.0f} wings of the {v['intrinsic/wings/n_genera']:.0f} genera "
    f"with ≥ {wings_min_genus} specimens (σ = {v['intrinsic/wings/sigma_over_spacing']:.2f} landmark spacings): the first "
    f"two α modes explain {100 * v['intrinsic/wings/alpha_ratio_1']:.1f} % and {100 * v['intrinsic/wings/alpha_ratio_2']:.1f} % "
    f"(Procrustes {100 * v['intrinsic/wings/procrustes_ratio_1']:.1f} %, {100 * v['intrinsic/wings/procrustes_ratio_2']:.1f} %); "
    f"{big2[0]} and {big2[1]} means differ by {v['intrinsic/wings/test_distance']:.3g} (p = {v['intrinsic/wings/test_p']:.3g})"
    + (f"; the α distances between genus means rank the genus pairs as the Procrustes angles do (Spearman "
       f"{v['intrinsic/wings/genus_distance_spearman']:.2f})" if "intrinsic/wings/genus_distance_spearman" in v else "")
    + ".",
    "",
    "![TD and ADHD means (α)](intrinsic_statistics/alpha_td_adhd_means.png)",
    "![α modes](intrinsic_statistics/alpha_modes.png)",
    "![age trend](intrinsic_statistics/age_trend.png)",
    "![wings](intrinsic_statistics/wings_genus_means.png)", "",
]
section = "\n".join(lines)
(__import__("pathlib").Path(output_dir) / "report_section.md").write_text(section)
print(section)

# %%
notes["intrinsic_statistics"] = ("Intrinsic statistics (beyond the paper): Fréchet means, tangent PCA, geodesic "
                                 "regression and the two-group mean test under the α (and Fisher–Rao) metric, "
                                 "with the Procrustes answers beside them; no paper values to compare with.")
record_values(output_dir, values, notes=notes, meta={
    "timings_s": timings, "analysed_subjects": sel.tolist(), "subset": sel[sub].tolist(),
    "params": {"n_shapes": n_shapes, "n_subset": n_subset, "sigma2": sigma2, "n_steps": n_steps, "tol": tol,
               "permutations": permutations, "fisher_rao": fisher_rao, "seed": seed}})
print(timings)
