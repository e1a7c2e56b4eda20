"""The zarr store of one matrix: creation, fingerprints (shapes, metric, parameters), resume, damage named."""

from __future__ import annotations

import hashlib
import inspect
import json
import warnings
from pathlib import Path

import numpy as np

from ..distances import metric_info
from ._blocks import ARRAYS, _n_blocks, block_pairs
from ._results import PairwiseResult

#: side of the stored chunks (a multiple of the block size near this)
CHUNK_SIDE = 64


_ATTR = "shapelib_pairwise"
_FORMAT = 1


def _jsonable(name, value):
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value)
    if value is None or isinstance(value, str):
        return value
    raise ValueError(f"parameter {name}={value!r} cannot be recorded in a pairwise store "
                     "(numbers, strings, booleans and None only)")


def _full_params(metric, rtol, params: dict) -> dict:
    """``params`` with the computing function's defaults filled in (so n_steps=16 == omitted)."""
    full = {}
    for name, p in inspect.signature(metric_info(metric).options_of(rtol)).parameters.items():
        if name in ("u", "v", "metric", "rtol") or p.kind in (p.VAR_KEYWORD, p.VAR_POSITIONAL):
            continue
        if name in params:
            full[name] = params[name]
        elif p.default is not p.empty:
            full[name] = p.default
    full.update(params)
    return {k: _jsonable(k, v) for k, v in sorted(full.items())}


def shapes_sha256(x: np.ndarray) -> str:
    """SHA-256 of the float64 shapes array and its shape."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    h = hashlib.sha256(repr(x.shape).encode())
    h.update(x.tobytes())
    return h.hexdigest()


# ---------------------------------------------------------------------------------------------
# The store
# ---------------------------------------------------------------------------------------------


class _Store:
    """The zarr group of one matrix in a directory; without a path, the same arrays in memory
    (NumPy: nothing to resume from, so nothing to gain from zarr's chunks and checksums)."""

    def __init__(self, group, path, attrs):
        self.group, self.path, self.attrs = group, path, attrs
        self.n, self.b = attrs["N"], attrs["block_size"]
        self.symmetric = attrs["symmetric"]
        self.nb = _n_blocks(self.n, self.b)
        if group is None:
            self.arrays = {name: np.full((self.n, self.n), fill, dtype=dtype) for name, (dtype, fill) in ARRAYS.items()}
            self.arrays["done"] = np.zeros((self.nb, self.nb), dtype=bool)
            return
        # every chunk is written, also one equal to the fill value (e.g. the all-NaN ``energy`` of a
        # non-path metric): a done block's chunk files must exist, which is how truncation is detected
        self.arrays = {name: group[name].with_config({"write_empty_chunks": True}) for name in (*ARRAYS, "done")}

    @property
    def where(self) -> str:
        return f"pairwise store {self.path}" if self.path else "in-memory pairwise store"

    @classmethod
    def create(cls, path, attrs):
        if path is None:
            return cls(None, None, attrs)
        import zarr
        from zarr.codecs import BytesCodec, Crc32cCodec, ZstdCodec

        store = zarr.storage.LocalStore(str(path))
        group = zarr.open_group(store, mode="w", zarr_format=3)
        b = attrs["block_size"]
        n = attrs["N"]
        chunk = min(n, b * max(1, CHUNK_SIDE // b))
        nb = _n_blocks(n, b)
        kw = dict(serializer=BytesCodec(), compressors=[ZstdCodec(level=3), Crc32cCodec()])
        for name, (dtype, fill) in ARRAYS.items():
            group.create_array(name, shape=(n, n), chunks=(chunk, chunk), dtype=dtype, fill_value=fill, **kw)
        group.create_array("done", shape=(nb, nb), chunks=(min(nb, CHUNK_SIDE),) * 2, dtype="bool",
                           fill_value=False, **kw)
        group.attrs[_ATTR] = attrs  # written last: a store without it is not a store
        return cls(group, str(path), attrs)

    @classmethod
    def open(cls, path):
        import zarr

        path = str(path)
        meta = Path(path) / "zarr.json"
        if not meta.is_file():
            raise ValueError(f"pairwise store {path}: no zarr.json (not a zarr v3 group, or truncated)")
        try:
            group = zarr.open_group(zarr.storage.LocalStore(path), mode="r+", zarr_format=3)
            attrs = dict(group.attrs[_ATTR])
        except KeyError as exc:
            raise ValueError(f"pairwise store {path}: a zarr group without the {_ATTR!r} attributes "
                             "(not a shapelib pairwise store, or its creation was interrupted)") from exc
        except Exception as exc:
            raise ValueError(f"pairwise store {path}: unreadable group metadata or attributes "
                             f"({type(exc).__name__}: {exc})") from exc
        for name in (*ARRAYS, "done"):
            try:
                group[name]
            except Exception as exc:
                raise ValueError(f"pairwise store {path}: array {name!r} is missing or its metadata is "
                                 f"unreadable ({type(exc).__name__}: {exc})") from exc
        return cls(group, path, attrs)

    # -- reading, with corruption named --------------------------------------------------------

    def _chunk_file(self, name, ci, cj):
        return Path(self.path) / name / "c" / str(ci) / str(cj)

    def _read(self, name, what_block):
        """The whole array; on failure, find and name the bad chunk(s)."""
        arr = self.arrays[name]
        try:
            return arr[...]
        except Exception as exc:
            cs = arr.chunks
            bad = []
            for ci in range(_n_blocks(arr.shape[0], cs[0])):
                for cj in range(_n_blocks(arr.shape[1], cs[1])):
                    try:
                        arr[ci * cs[0]:(ci + 1) * cs[0], cj * cs[1]:(cj + 1) * cs[1]]
                    except Exception:
                        bad.append((ci, cj))
            where = "; ".join(what_block(name, ci, cj) for ci, cj in bad) or "unknown chunk"
            raise ValueError(f"{self.where}: array {name!r} is corrupt or truncated ({where}): "
                             f"{type(exc).__name__}: {exc}. Delete the store (or that chunk file and the "
                             "matching 'done' entries) and rerun to recompute.") from exc

    def _describe_data_chunk(self, name, ci, cj):
        c = self.arrays[name].chunks[0]
        rows = f"{ci * c}:{min((ci + 1) * c, self.n)}"
        cols = f"{cj * c}:{min((cj + 1) * c, self.n)}"
        k = c // self.b
        return (f"chunk {name}/c/{ci}/{cj}, pairs [{rows}, {cols}], blocks "
                f"[{ci * k}:{min((ci + 1) * k, self.nb)}, {cj * k}:{min((cj + 1) * k, self.nb)}]")

    def _describe_done_chunk(self, name, ci, cj):
        c = self.arrays["done"].chunks[0]
        return f"chunk done/c/{ci}/{cj}, blocks [{ci * c}:{(ci + 1) * c}, {cj * c}:{(cj + 1) * c}]"

    def done(self) -> np.ndarray:
        return self._read("done", self._describe_done_chunk)

    def task_done(self, done=None) -> set:
        done = self.done() if done is None else done
        return {(a, b) for a, b in block_pairs(self.n, self.b, symmetric=self.symmetric) if done[a, b]}

    def read(self) -> tuple[dict, np.ndarray]:
        """All arrays and the pair-level ``computed`` mask; checks every done block is really there."""
        done = self.done()
        computed = np.zeros((self.n, self.n), dtype=bool)
        for a, b in self.task_done(done):
            for p, q in ((a, b), (b, a)) if self.symmetric else ((a, b),):
                computed[p * self.b:(p + 1) * self.b, q * self.b:(q + 1) * self.b] = True
        if self.path is not None:  # a done block must have its chunk files on disk
            for name in ARRAYS:
                c = self.arrays[name].chunks[0]
                for ci, cj in {(p * self.b // c, q * self.b // c) for p, q in zip(*np.nonzero(done))}:
                    if not self._chunk_file(name, ci, cj).is_file():
                        raise ValueError(f"{self.where}: array {name!r} is truncated: "
                                         f"{self._describe_data_chunk(name, ci, cj)} of a done block is missing")
        data = {name: self._read(name, self._describe_data_chunk) for name in ARRAYS}
        # a done pair must have a value: a NaN there is damage, never a result
        holes = computed & (np.isnan(data["matrix"]) | np.isnan(data["upper"]) | (data["n_iter"] < 0))
        if holes.any():
            i, j = np.argwhere(holes)[0]
            raise ValueError(f"{self.where}: pair ({i}, {j}) of done block ({i // self.b}, {j // self.b}) "
                             "has no value: the store is corrupt")
        return data, computed

    # -- writing --------------------------------------------------------------------------------

    def write_block(self, a: int, b: int, out: dict) -> None:
        """Write block ``(a, b)``'s data (and its mirror for symmetric metrics), then its done flag."""
        s = self.b
        ra, rb = slice(a * s, min((a + 1) * s, self.n)), slice(b * s, min((b + 1) * s, self.n))
        for name in ARRAYS:
            self.arrays[name][ra, rb] = out[name]
            if self.symmetric and a != b:
                self.arrays[name][rb, ra] = out[name].T
        if self.symmetric and a != b:
            self.arrays["done"][b, a] = True
        self.arrays["done"][a, b] = True


def _check_same(store: _Store, want: dict, *, block_size_given) -> None:
    have = store.attrs
    for key, what in (("N", "number of shapes"), ("K", "landmarks per shape"), ("d", "dimension"),
                      ("shapes_sha256", "shapes (SHA-256)"), ("metric", "metric"), ("rtol", "rtol")):
        if have.get(key) != want[key]:
            raise ValueError(f"{store.where} was computed with {what} {have.get(key)!r}, "
                             f"not {want[key]!r}: use another store (or delete this one)")
    if have.get("params") != want["params"]:
        old, new = have.get("params") or {}, want["params"]
        diff = {k: (old.get(k), new.get(k)) for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)}
        text = ", ".join(f"{k}: stored {o!r}, given {n!r}" for k, (o, n) in diff.items())
        raise ValueError(f"{store.where} was computed with other parameters ({text}): use another store "
                         "(or delete this one)")
    if block_size_given is not None and block_size_given != have["block_size"]:
        raise ValueError(f"{store.where} has block_size {have['block_size']}, not {block_size_given}: "
                         "omit block_size to resume it")
    if have.get("shapelib_version") != want["shapelib_version"]:
        warnings.warn(f"{store.where} was written by shapelib {have.get('shapelib_version')}, this is "
                      f"{want['shapelib_version']}: resuming mixes the two versions' results", stacklevel=3)


def open_store(path) -> PairwiseResult:
    """Read a finished or partial pairwise store (see the module docstring).

    Raises ``ValueError`` naming the store and the array/block when it is corrupt or truncated.
    Pairs not yet computed are NaN in the float arrays and ``False`` in ``result.computed``.

    Parameters
    ----------
    path : str or Path
        The zarr directory that ``compute_pairwise(..., store=path)`` wrote.

    Returns
    -------
    PairwiseResult
        The stored arrays (``matrix`` and the ``lower``, ``upper``, ``converged`` … of every
        pair), the metric and its parameters as recorded, ``computed`` and ``log``
        (``blocks_done`` of ``blocks_total``).

    Raises
    ------
    ValueError
        When ``path`` is not a pairwise store, or a chunk is missing, unreadable or fails its
        checksum (naming the array and the block).

    See Also
    --------
    compute_pairwise : Writes the store, and resumes it.

    Examples
    --------
    >>> import tempfile
    >>> from pathlib import Path
    >>> import numpy as np
    >>> from shapelib.pairwise import compute_pairwise, open_store
    >>> x = np.random.default_rng(0).normal(size=(4, 6, 2))
    >>> tmp = tempfile.TemporaryDirectory()
    >>> store = Path(tmp.name) / "procrustes.zarr"
    >>> r = compute_pairwise(x, metric="procrustes", store=store, n_jobs=1, progress=False)
    >>> back = open_store(store)
    >>> back.metric, back.complete, np.array_equal(back.matrix, r.matrix)
    ('procrustes', True, True)
    >>> tmp.cleanup()
    """
    store = _Store.open(path)
    data, computed = store.read()
    return _result(store, data, computed, log={"blocks_total": len(block_pairs(store.n, store.b,
                                                                               symmetric=store.symmetric)),
                                               "blocks_done": len(store.task_done())})


def _result(store: _Store, data: dict, computed, log) -> PairwiseResult:
    params = dict(store.attrs["params"])
    if store.attrs.get("rtol") is not None:
        params["rtol"] = store.attrs["rtol"]
    return PairwiseResult(matrix=data["matrix"], lower=data["lower"], upper=data["upper"],
                          energy=data["energy"], seconds=data["seconds"], converged=data["converged"],
                          n_iter=data["n_iter"], metric=store.attrs["metric"], params=params,
                          store=store.path, computed=computed, log=log, symmetric=bool(store.symmetric))


def _stored_seconds_per_pair(store: _Store) -> float | None:
    done = store.task_done()
    if not done:
        return None
    a, b = next(iter(done))
    s = store.b
    try:
        sec = store.arrays["seconds"][a * s:(a + 1) * s, b * s:(b + 1) * s]
    except Exception:
        return None  # read() names the damage later
    sec = sec[np.isfinite(sec) & (sec > 0)]
    return float(sec.mean()) if sec.size else None


def _pairs_left(st, n, symmetric) -> int:
    if st is None:
        return n * (n - 1) // 2 if symmetric else n * (n - 1)
    done = st.task_done()
    return sum(_block_n_pairs(st, a, b) for a, b in block_pairs(n, st.b, symmetric=symmetric)
               if (a, b) not in done)


def _token(want: dict, block_size: int) -> str:
    """Task-key prefix: the same computation (shapes, metric, parameters, blocks) has the same keys."""
    body = {k: v for k, v in want.items() if k != "shapelib_version"}
    return hashlib.sha256(json.dumps({**body, "block_size": block_size}, sort_keys=True).encode()).hexdigest()[:16]


def _rows(st: _Store, a: int) -> slice:
    return slice(a * st.b, min((a + 1) * st.b, st.n))


def _block_n_pairs(st: _Store, a: int, b: int) -> int:
    ra, rb = _rows(st, a), _rows(st, b)
    na, nb = ra.stop - ra.start, rb.stop - rb.start
    if a != b:
        return na * nb
    return na * (na - 1) // 2 if st.symmetric else na * (na - 1)
