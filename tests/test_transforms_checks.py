"""shapelib.pointsets._transforms (the parametrised transforms of the pose search) against independent
values: the start is the base scaled by ``scale0`` (the identity rotation, no translation), the rotation
of an angle or of an unnormalised quaternion is SciPy's, the similarity's scale is ``exp`` of its
parameter, and ``chain`` is the gradient of a function of the moved points by finite differences."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shapelib.pointsets._transforms import Model


def base(d, mirror=False):
    b = Rotation.from_rotvec([0.0, 0.0, 0.7]).as_matrix()[:2, :2] if d == 2 else Rotation.random(
        random_state=7).as_matrix()
    return b @ np.diag([-1.0] + [1.0] * (d - 1)) if mirror else b


@pytest.mark.parametrize("transform", ["rigid", "similarity", "affine"])
@pytest.mark.parametrize("d", [2, 3])
def test_the_start_is_the_base_scaled_by_scale0_with_no_translation(transform, d):
    b = base(d, mirror=True)
    for scale0, expected in [(None, 1.0), (1.7, 1.7)]:
        m = Model(transform, d, b) if scale0 is None else Model(transform, d, b, scale0)
        p = m.start()
        a, t, _ = m.matrix(p)
        factor = 1.0 if transform == "rigid" else expected  # a rigid transform has no scale to start at
        assert np.allclose(a, factor * b, atol=1e-14) and np.array_equal(t, np.zeros(d))
        assert p.dtype == np.float64 and len(p) == m.n_lin + d


@pytest.mark.parametrize("transform", ["rigid", "similarity"])
def test_the_rotation_of_an_angle_or_a_quaternion_is_scipys_and_the_scale_is_exp(transform):
    rng = np.random.default_rng(0)
    for d in (2, 3):
        b = base(d)
        m = Model(transform, d, b)
        log_s = [0.4] if transform == "similarity" else []
        t = rng.normal(size=d)
        if d == 2:
            lin = [1.1]
            r = Rotation.from_rotvec([0.0, 0.0, 1.1]).as_matrix()[:2, :2]
        else:
            q = np.array([0.3, -1.2, 0.5, 2.0])  # (w, x, y, z), not of unit length: the map normalises it
            lin = list(q)
            r = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_matrix()  # SciPy's order is (x, y, z, w)
        a, tt, _ = m.matrix(np.array(lin + log_s + list(t)))
        s = np.exp(0.4) if transform == "similarity" else 1.0
        assert np.allclose(a, s * r @ b, atol=1e-12) and np.array_equal(tt, t)


@pytest.mark.parametrize("transform", ["rigid", "similarity", "affine"])
@pytest.mark.parametrize("d", [2, 3])
def test_chain_is_the_gradient_of_a_function_of_the_moved_points(transform, d):
    rng = np.random.default_rng(d)
    x = rng.normal(size=(7, d))
    c = rng.normal(size=(7, d))
    m = Model(transform, d, base(d), 1.3)
    p = m.start() + 0.3 * rng.normal(size=m.start().shape)

    def f(pp):
        a, t, _ = m.matrix(pp)
        return float(np.sum(np.sin((x @ a.T + t) * c)))

    a, t, _ = m.matrix(p)
    gx = c * np.cos((x @ a.T + t) * c)  # ∂f/∂z at z = A x + t
    eps = 1e-6
    fd = np.array([(f(p + eps * e) - f(p - eps * e)) / (2 * eps) for e in np.eye(len(p))])
    assert np.allclose(m.chain(p, x, gx), fd, atol=1e-7)
