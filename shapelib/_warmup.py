"""Compile the numba kernels once, into numba's on-disk cache (``python -m shapelib._warmup``).

The compiled loops (:mod:`shapelib.geometry._kernels`, :mod:`shapelib.pointsets._coherent_em`) are
compiled on their first call and cached beside their sources (``cache=True``): the first
registration or geodesic of a fresh installation waits for the compiler (48 s in
all on an idle 2-core machine), later ones and later processes read the cache. ``make setup`` runs this
module after installing, so that neither the first test run nor the first notebook pays for it:
one tiny registration and one tiny geodesic of each metric in 2-D and 3-D reach every kernel with
the argument types the library passes.
"""

from __future__ import annotations

import time
import warnings

import numpy as np


def compile_kernels() -> float:
    """Call every compiled kernel once (2-D and 3-D, both metrics); returns the seconds it took."""
    from .pointsets.registration import register
    from .solver.geodesic import geodesic

    t0 = time.perf_counter()
    rng = np.random.default_rng(0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # tiny, arbitrary problems: their warnings say nothing
        for d in (2, 3):
            x = rng.normal(size=(12, d))
            y = x + 0.05 * rng.normal(size=(12, d))
            register(x, y, n_threads=1)
            for metric in ("alpha", "fisher_rao"):  # two points: a 3-D Fisher–Rao path of five takes seconds
                geodesic(x[:2], y[:2], sigma2=0.5, metric=metric)
    return time.perf_counter() - t0


if __name__ == "__main__":  # pragma: no cover - run by make setup
    print(f"shapelib: numba kernels compiled and cached in {compile_kernels():.0f} s")
