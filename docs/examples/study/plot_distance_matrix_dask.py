"""
A distance matrix on Dask
=========================

:func:`shapelib.pairwise_distances` computes the distances of all pairs in blocks. With
``n_jobs=k`` it starts a Dask cluster of ``k`` worker processes; with ``client=`` it runs on a
cluster you already have (here a small one of threads, so that this page runs anywhere); with
``store=`` every finished block is kept in a zarr store on disk, and the same call after an
interruption computes only the blocks that are missing.
"""

# %%
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
from distributed import Client, LocalCluster

import shapelib as sl
from shapelib.datasets import load_corpus_callosum

raw, _ = load_corpus_callosum()
x = sl.to_centroid_size(raw)
store = Path(tempfile.mkdtemp()) / "alpha.zarr"

cluster_options = dict(n_workers=2, threads_per_worker=1, processes=False,
                       dashboard_address=None)
with LocalCluster(**cluster_options) as cluster, Client(cluster) as client:
    result = sl.pairwise_distances(x, metric="alpha", sigma2=0.5, rtol=1e-2,
                                   client=client, store=store, block_size=8,
                                   progress=False, return_result=True)
print(result.summary())
print(result.log)

# %%
# The store keeps the blocks: the same call again reads them instead of computing them.
again = sl.pairwise_distances(x, metric="alpha", sigma2=0.5, rtol=1e-2, store=store,
                              block_size=8, progress=False, return_result=True)
print(again.log)  # every block found done in the store

fig, ax = plt.subplots(figsize=(4, 3.4))
im = ax.imshow(result.matrix, cmap="viridis")
fig.colorbar(im, ax=ax, label="α distance")
ax.set_title("7 corpus callosum outlines")
plt.show()

# %%
# In a script of your own, start the worker processes under ``if __name__ == "__main__":``
# (Python's rule for multiprocessing) and pass ``n_jobs=4``; on a cluster, pass its
# ``client=`` or ``scheduler="tcp://host:8786"`` (:doc:`/guide/population`).
