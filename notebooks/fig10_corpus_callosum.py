# %% [markdown]
# # Figure 10 — the corpus callosum shapes
#
# The paper's Figure 10 shows nine corpus callosum outlines, 63 landmarks each, used for the
# pairwise comparison of Table I. Seven of them are public (`cdfhc_data2D_CC.mat`, variable
# `CC7`); they are the paper's shapes **1, 3, 8, 2, 6, 7, 9** in file order (the Procrustes
# column of Table I confirms the mapping, see `table1_pairwise`). Shapes 4 and 5 are not
# available, so their panels are left empty here.

# %% tags=["parameters"]
from shapelib.study import default_output_dir
output_dir = default_output_dir("fig10_corpus_callosum")  # run_all.py passes its own

# %%
import matplotlib.pyplot as plt
import numpy as np

from shapelib.datasets import load_corpus_callosum
from shapelib.study import record_values, record_verdict, save_figure

shapes, paper_ids = load_corpus_callosum()
by_id = dict(zip(paper_ids.tolist(), shapes))
print(shapes.shape, paper_ids)

# %%
fig, axes = plt.subplots(3, 3, figsize=(9, 5.4))
lo, hi = shapes.reshape(-1, 2).min(0), shapes.reshape(-1, 2).max(0)
pad = 0.05 * (hi - lo)
for pid, ax in zip(range(1, 10), axes.ravel()):
    ax.set_aspect("equal")
    ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
    ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
    ax.set_xticks([])
    ax.set_yticks([])
    if pid in by_id:
        s = by_id[pid]
        closed = np.vstack([s, s[:1]])
        ax.plot(closed[:, 0], closed[:, 1], "-", color="0.4", lw=1)
        ax.plot(s[:, 0], s[:, 1], "k.", ms=3)
        ax.set_title(f"shape {pid}", fontsize=10)
    else:
        ax.set_title(f"shape {pid} (not public)", fontsize=10, color="0.5")
        for side in ax.spines.values():
            side.set_linestyle(":")
fig.suptitle("Corpus callosum shapes, 63 landmarks each (paper Fig. 10; ids as in Table I)")
fig.tight_layout()
save_figure(fig, output_dir, "fig10_corpus_callosum")

# %%
record_values(
    output_dir,
    {"fig10/n_shapes": len(shapes), "fig10/n_landmarks": shapes.shape[1]},
    notes={"fig10": "7 of the paper's 9 shapes are public; shapes 4 and 5 are missing."},
    meta={"paper_ids_in_file_order": paper_ids.tolist()},
)

# %%
missing = sorted(set(range(1, 10)) - set(int(i) for i in paper_ids))
record_verdict(output_dir, "fig10", "reproduced with a difference" if shapes.shape[1] == 63 else "not reproduced",
               f"{len(shapes)} of the paper's 9 shapes with {shapes.shape[1]} landmarks each (paper: 63); shapes "
               f"{', '.join(map(str, missing))} are not public and are left empty.")
