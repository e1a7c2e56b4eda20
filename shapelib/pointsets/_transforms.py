"""Parametrised transforms ``x ↦ A x + t`` for the pose search, with ``∂A/∂p`` in closed form.

``A = s R(r) B``: ``B`` a fixed start (a rotation of the global search, possibly a mirror),
``R(r)`` a rotation by an angle (2-D) or by a quaternion ``q`` normalised in the map
(3-D, ``R = M(q)/|q|²`` with ``M`` the quadratic rotation matrix of ``q``), ``s = e^{log s}``
for similarities; an affine ``A`` is its own ``d²`` parameters. Translations ``t`` come last.
"""

from __future__ import annotations

import numpy as np

TRANSFORMS = ("rigid", "similarity", "affine")


def _quat_m(q):
    w, x, y, z = q
    m = np.array([[w*w + x*x - y*y - z*z, 2*(x*y - w*z), 2*(x*z + w*y)],
                  [2*(x*y + w*z), w*w - x*x + y*y - z*z, 2*(y*z - w*x)],
                  [2*(x*z - w*y), 2*(y*z + w*x), w*w - x*x - y*y + z*z]])
    dm = 2 * np.array([
        [[w, -z, y], [z, w, -x], [-y, x, w]],
        [[x, y, z], [y, -x, -w], [z, w, -x]],
        [[-y, x, w], [x, y, z], [-w, z, -y]],
        [[-z, -w, x], [w, -z, y], [x, y, z]],
    ])
    return m, dm


class Model:
    """The map from parameters ``p`` to ``(A, t)`` and ``∂A/∂p`` for one transform type and start."""

    def __init__(self, transform: str, d: int, base: np.ndarray, scale0: float = 1.0):
        self.transform, self.d, self.base = transform, d, np.asarray(base, dtype=float)
        self.scale0 = scale0
        if transform == "affine":
            self.n_lin = d * d
        else:
            self.n_lin = (1 if d == 2 else 4) + (transform == "similarity")

    def start(self) -> np.ndarray:
        if self.transform == "affine":
            lin = (self.scale0 * self.base).ravel()
        elif self.d == 2:
            lin = [0.0] + ([np.log(self.scale0)] if self.transform == "similarity" else [])
        else:
            lin = [1.0, 0.0, 0.0, 0.0] + ([np.log(self.scale0)] if self.transform == "similarity" else [])
        return np.concatenate([np.asarray(lin, dtype=float), np.zeros(self.d)])

    def matrix(self, p):
        """``A`` (d, d), ``t`` (d,) and ``dA`` (n_lin, d, d)."""
        d = self.d
        lin, t = p[:self.n_lin], p[self.n_lin:]
        if self.transform == "affine":
            return lin.reshape(d, d), t, np.eye(d * d).reshape(d * d, d, d)
        if d == 2:
            c, s = np.cos(lin[0]), np.sin(lin[0])
            r = np.array([[c, -s], [s, c]])
            dr = np.array([[[-s, -c], [c, -s]]])
            k = 1
        else:
            q = lin[:4]
            n2 = float(q @ q)
            m, dm = _quat_m(q)
            r = m / n2
            dr = dm / n2 - 2 * q[:, None, None] * m[None] / n2 ** 2
            k = 4
        sc = np.exp(lin[k]) if self.transform == "similarity" else 1.0
        a = sc * r @ self.base
        da = sc * np.einsum("kij,jl->kil", dr, self.base)
        if self.transform == "similarity":
            da = np.concatenate([da, a[None]])
        return a, t, da

    def chain(self, p, x, gx):
        """``∂f/∂p`` from ``gx = ∂f/∂(A x + t)`` (n, d) at the points ``x``."""
        _, _, da = self.matrix(p)
        ga = gx.T @ x  # ∂f/∂A_kl = Σ_i g_ik x_il
        return np.concatenate([np.einsum("kij,ij->k", da, ga), gx.sum(axis=0)])
