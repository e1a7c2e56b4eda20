# %% [markdown]
# # Tutorial — your own landmarks, from a `.tps` file to distances, trees, ordinations and geodesics
#
# A morphometrician's data usually arrive as a tpsDig `.tps` file (or a spreadsheet). This
# notebook walks the whole path on such a file:
#
# 1. **a `.tps` file** — here written from landmarks sampled on MPEG-7 silhouettes (the shapes the
#    study already fetches), so that the tutorial runs anywhere; replace `tps_file` by your own;
# 2. **reading it** with `shapelib.io.read_landmarks` (`.tps`, `.csv`, `.npy`/`.npz`);
# 3. **aligning** the shapes (generalized Procrustes) and bringing them to a scale that fits σ²;
# 4. **distance matrices** under three metrics;
# 5. a **dendrogram** (SciPy) and an **MDS ordination** (scikit-learn);
# 6. a **geodesic** between two specimens, as a figure and an animation.
#
# The same steps on the command line are in the documentation's guide "Your own data" (docs/guide/own-data.md).

# %% tags=["parameters"]
from shapelib.study import default_output_dir
output_dir = default_output_dir("tutorial_own_data")  # run_all.py passes its own
classes = ["fish", "Heart", "Bone"]         # MPEG-7 classes sampled into the example .tps file
per_class = 3                               # specimens per class
n_landmarks = 24                            # landmarks per outline
centroid_size = 20.0                        # the study's scale (shapelib.geometry.scale.PAPER_CENTROID_SIZE)
sigma2 = 0.5                                # σ² of the Gaussian mixture (eq. 5)
metrics = ["procrustes", "alpha", "fisher_rao"]
n_steps = 8                                 # time steps of each geodesic
n_jobs = None                               # worker processes for the distance matrices (None: chosen)
geodesic_metric = "alpha"

# %%
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from IPython.display import Image, display

from shapelib import io, pairwise_distances
from shapelib.datasets import mpeg7_landmarks
from shapelib.distances import path_result
from shapelib.geometry.scale import landmark_spacing, sigma_ratio, to_centroid_size
from shapelib.study import record_values, save_figure

out = Path(output_dir)
out.mkdir(parents=True, exist_ok=True)
values = {}

# %% [markdown]
# ## 1. A `.tps` file
#
# `mpeg7_landmarks(name, n)` places `n` landmarks evenly by arc length on a silhouette's outline,
# in pixel coordinates, as a digitiser would. We write them as tpsDig does: one `LM=` block per
# specimen, then `IMAGE=` and `ID=`.

# %%
names = [f"{c}-{i}" for c in classes for i in range(1, per_class + 1)]
# Outlines touching the image border lie half a pixel outside it (x = -0.5); a digitiser records
# pixel coordinates >= 0, and tpsDig reads negative ones as missing landmarks: shift by one pixel.
pixels = np.stack([mpeg7_landmarks(name, n_landmarks) for name in names]) + 1.0
tps_file = out / "mpeg7_sample.tps"
io.write_landmarks(tps_file, pixels, pd.DataFrame({"id": names, "image": [f"{n}.gif" for n in names]}))
print("".join(tps_file.read_text().splitlines(keepends=True)[: n_landmarks + 4]))

# %% [markdown]
# ## 2. Reading it
#
# `read_landmarks` returns an `(N, K, d)` float64 array and a table of specimens (`id` first).
# Broken files (a missing landmark, a wrong `LM=` count, a non-numeric cell) raise a `ValueError`
# naming the file, the line, the specimen and the landmark. tpsDig codes missing landmarks as
# negative coordinates: they are an error unless you pass `missing="nan"`.

# %%
shapes, specimens = io.read_landmarks(tps_file)
specimens["class"] = [n.split("-")[0] for n in specimens["id"]]
display(specimens[["id", "image", "scale", "n_missing", "class"]])

# what a broken file looks like: one landmark of the third specimen recorded as missing (-1 -1)
broken = out / "broken.tps"
lines = tps_file.read_text().splitlines()
block = 2 * (n_landmarks + 4)  # LM=, K rows, IMAGE=, ID=, blank line
lines[block + 1 + 4] = "-1 -1"
broken.write_text("\n".join(lines) + "\n")
try:
    io.read_landmarks(broken)
except ValueError as exc:
    print("ValueError:", exc)
values["tutorial/n_specimens"] = len(shapes)
values["tutorial/n_landmarks"] = shapes.shape[1]
values["tutorial/tps_roundtrip_max_abs_diff"] = float(np.max(np.abs(shapes - pixels)))
assert values["tutorial/tps_roundtrip_max_abs_diff"] == 0.0

# %% [markdown]
# ## 3. Alignment and scale
#
# Generalized Procrustes analysis removes position, size and rotation. σ² is measured in the
# units of the coordinates, so the shapes must be brought to a scale that fits it: the study
# scales every aligned shape to centroid size 20 (`shapelib.to_centroid_size`), where σ = √0.5
# is of the order of the spacing of neighbouring landmarks (`shapelib.geometry.scale.sigma_ratio`, printed
# below). In pixels, the same σ² would be far below it: the mixture would be isolated spikes.

# %%
aligned = to_centroid_size(shapes, size=centroid_size)  # generalized Procrustes, then centroid size
io.write_landmarks(out / "aligned.csv", aligned, specimens[["id", "class"]])
values["tutorial/mean_landmark_spacing"] = landmark_spacing(aligned)
values["tutorial/sigma_over_spacing"] = sigma_ratio(aligned, sigma2=sigma2)
print(f"pixels: sigma / spacing = {sigma_ratio(shapes, sigma2=sigma2):.3f}; "
      f"centroid size {centroid_size:g}: sigma / spacing = {sigma_ratio(aligned, sigma2=sigma2):.2f}")

colors = dict(zip(classes, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
fig, axes = plt.subplots(1, 2, figsize=(10, 4))
for s, c in zip(shapes, specimens["class"]):
    axes[0].plot(*np.vstack([s, s[:1]]).T, "-", color=colors[c], lw=0.8)
for s, c in zip(aligned, specimens["class"]):
    axes[1].plot(*np.vstack([s, s[:1]]).T, "-", color=colors[c], lw=0.8)
axes[0].set_title("as digitised (pixels)")
axes[1].set_title(f"Procrustes aligned, centroid size {centroid_size:g}")
for ax in axes:
    ax.set_aspect("equal")
for c in classes:
    axes[1].plot([], [], color=colors[c], label=c)
axes[1].legend(fontsize=8)
fig.tight_layout()
save_figure(fig, output_dir, "tutorial_aligned")
plt.show()

# %% [markdown]
# ## 4. Distance matrices
#
# `pairwise_distances(..., return_result=True)` returns the matrix with each pair's diagnostics
# (bounds, convergence); `store="name.zarr"` would make a long run resumable. The information
# metrics (`alpha`, `fisher_rao`) report a certified bracket `lower ≤ d ≤ upper`.

# %%
matrices = {}
for metric in metrics:
    params = {"sigma2": sigma2} if metric in ("alpha", "fisher_rao", "alpha_bound", "fisher_rao_bound") else {}
    if metric in ("alpha", "fisher_rao"):
        params["n_steps"] = n_steps
    result = pairwise_distances(aligned, metric=metric, n_jobs=n_jobs, progress=False, return_result=True, **params)
    frame = pd.DataFrame(result.matrix, index=pd.Index(specimens["id"], name="id"), columns=specimens["id"])
    frame.to_csv(out / f"distances_{metric}.csv")
    matrices[metric] = frame
    n_pairs = len(result.to_frame())
    values[f"tutorial/{metric}/n_pairs"] = n_pairs
    n_failed = len(result.nonconverged_pairs())
    values[f"tutorial/{metric}/converged_fraction"] = 1.0 - n_failed / n_pairs
    values[f"tutorial/{metric}/max_asymmetry"] = float(np.max(np.abs(result.matrix - result.matrix.T)))
    print(f"{metric}: {n_pairs} pairs, {n_failed} not converged")
display(matrices[metrics[1]].round(3))

# %% [markdown]
# ## 5. Dendrogram and MDS ordination
#
# Average-linkage trees (`scipy.cluster.hierarchy`) and metric MDS on the precomputed distances
# (`sklearn.manifold.MDS`, started from classical MDS). The cophenetic correlation says how
# faithfully each tree keeps the distances; a class is "recovered" when its specimens form one
# cluster of the tree cut into as many clusters as there are classes.

# %%
from scipy.cluster.hierarchy import cophenet, dendrogram, fcluster, linkage
from scipy.spatial.distance import squareform
from sklearn.manifold import MDS

fig, axes = plt.subplots(2, len(metrics), figsize=(4.2 * len(metrics), 7.5))
for col, metric in enumerate(metrics):
    d = matrices[metric].to_numpy()
    d = 0.5 * (d + d.T)  # exactly symmetric (the computed matrix is symmetric to rounding)
    condensed = squareform(d, checks=False)
    tree = linkage(condensed, method="average")
    values[f"tutorial/{metric}/cophenetic_correlation"] = float(cophenet(tree, condensed)[0])
    labels = fcluster(tree, t=len(classes), criterion="maxclust")
    recovered = sum(len(set(labels[specimens["class"].to_numpy() == c])) == 1
                    and np.sum(labels == labels[specimens["class"].to_numpy() == c][0]) == per_class for c in classes)
    values[f"tutorial/{metric}/classes_recovered"] = int(recovered)
    dendrogram(tree, labels=list(specimens["id"]), ax=axes[0, col], leaf_rotation=90, leaf_font_size=7,
               color_threshold=0, above_threshold_color="k")
    for tick in axes[0, col].get_xticklabels():
        tick.set_color(colors[tick.get_text().split("-")[0]])
    axes[0, col].set_title(f"{metric}: cophenetic r = {values[f'tutorial/{metric}/cophenetic_correlation']:.2f}")
    xy = MDS(n_components=2, metric="precomputed", init="classical_mds", random_state=0).fit_transform(d)
    for c in classes:
        m = specimens["class"].to_numpy() == c
        axes[1, col].scatter(xy[m, 0], xy[m, 1], color=colors[c], label=c, s=25)
    axes[1, col].set_title(f"{metric}: MDS")
    axes[1, col].set_aspect("equal", adjustable="datalim")
axes[1, 0].legend(fontsize=8)
fig.tight_layout()
save_figure(fig, output_dir, "tutorial_dendrogram_mds")
plt.show()

# %% [markdown]
# ## 6. A geodesic, as a figure and an animation
#
# `path_result` returns the whole geodesic (eqs. 8–12): the intermediate shapes are the intrinsic
# deformation from one specimen to the other. `shapelib.plotting.animate_geodesic` turns it into a
# matplotlib animation; `PillowWriter` saves it as a GIF.

# %%
from matplotlib.animation import PillowWriter

from shapelib.plotting import animate_geodesic
from shapelib.plotting import plot_trajectories

a, b = 0, per_class  # first specimen of the first two classes
geo = path_result(aligned[a], aligned[b], metric=geodesic_metric, sigma2=sigma2, n_steps=n_steps)
print(geo.summary())
values["tutorial/geodesic/length"] = geo.length
values["tutorial/geodesic/lower_bound"] = geo.lower_bound
values["tutorial/geodesic/converged"] = float(geo.converged)

fig, ax = plt.subplots(figsize=(5, 5))
ax.plot(*np.vstack([aligned[a], aligned[a][:1]]).T, "--", color="0.6", lw=0.8)
ax.plot(*np.vstack([aligned[b], aligned[b][:1]]).T, "-", color="0.6", lw=0.8)
plot_trajectories(ax, geo.path)
ax.set_title(f"{geodesic_metric} geodesic {names[a]} → {names[b]}")
save_figure(fig, output_dir, "tutorial_geodesic")
plt.show()

anim = animate_geodesic(geo, title=f"{names[a]} → {names[b]}")
gif = out / "tutorial_geodesic.gif"
anim.save(gif, writer=PillowWriter(fps=6))
plt.close(anim._fig)
display(Image(filename=str(gif)))

_ = record_values(output_dir, values, notes={
    "tutorial": f"MPEG-7 classes {classes}, {per_class} each, {n_landmarks} landmarks, centroid size "
                f"{centroid_size:g}, sigma2 {sigma2}; metrics {metrics}."})
