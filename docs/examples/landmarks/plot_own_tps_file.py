"""
Your own tpsDig file
====================

Landmarks digitised with tpsDig come as ``.tps`` files: one block per specimen, ``LM=`` with the
number of landmarks, their coordinates, then ``ID=``, ``IMAGE=`` and ``SCALE=``. This example
writes such a file (from the study's corpus callosum outlines, to have one at hand), reads it as
your own file would be read, aligns the shapes and compares them.
"""

# %%
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
from scipy.cluster.hierarchy import dendrogram, linkage
from scipy.spatial.distance import squareform

import shapelib as sl
from shapelib import io
from shapelib.datasets import load_corpus_callosum

folder = Path(tempfile.mkdtemp())
raw, paper_ids = load_corpus_callosum()
names = [f"cc-{i}" for i in paper_ids]
path = io.write_tps(folder / "callosum.tps", raw, specimens=names)
print("".join(path.read_text().splitlines(True)[:4]), "...")

# %%
# Reading it: the coordinates as an ``(N, K, 2)`` array and a table of the specimens (``ID=``,
# ``IMAGE=``, ``SCALE=``, missing landmarks). A broken file or a missing landmark (tpsDig writes
# negative coordinates) stops with an error that names the file, line, specimen and landmark.
shapes, specimens = io.read_tps(path)
ids = specimens["id"].tolist()
print(shapes.shape)
print(specimens[["id", "line", "n_missing"]])

# %%
# Aligned (generalized Procrustes) and brought to the study's scale, where σ² = 0.5 suits
# outlines of this density; then the α-order distance matrix, certified to 1 %.
x = sl.to_centroid_size(shapes)
print(f"sigma = {sl.sigma_ratio(x, sigma2=0.5):.2f} landmark spacings at sigma2 = 0.5")
D = sl.pairwise_distances(x, metric="alpha", sigma2=0.5, rtol=1e-2, progress=False)

fig, ax = plt.subplots(figsize=(5, 3))
dendrogram(linkage(squareform(D, checks=False), method="average"), labels=ids, ax=ax)
ax.set_title("average-linkage clustering, α distance")
plt.show()

# %%
# The same on the command line: ``shapelib info callosum.tps``, ``shapelib align callosum.tps -o
# aligned.tps --size 20``, ``shapelib distances aligned.tps --metric alpha --sigma2 0.5``
# (:doc:`/guide/own-data`).
