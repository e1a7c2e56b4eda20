r"""σ² from the data: the free parameter of the GMM shape (eq. 5) estimated from a population.

The paper fixes σ² by hand (0.1, 0.5, 1.5) and names "estimating the free parameter σ² directly
from the data" as its next step. Two estimators, both of the landmarks' own variability:

Landmark scatter (``scatter_sigma2``; the rule :func:`shapelib.estimate_sigma2` uses)
    The generative reading of eq. (5): landmark ``a`` of shape ``i`` is a noisy observation of
    its mixture component, ``x_ia = μ_a + ε_ia``, ``ε ~ N(0, σ² I_d)`` independent. The maximum
    likelihood estimate of σ² is the mean squared deviation of the landmarks from the mean shape
    per coordinate; with the unbiased denominator,

    .. math::

        \hat\sigma^2 = \frac{\sum_{i,a} |x_{ia} - \bar x_a|^2}{(N - 1) K d}, \qquad
        \operatorname{se}(\hat\sigma^2) = \hat\sigma^2 \sqrt{\frac{2}{(N - 1) K d}}.

    What it means for the distances: the overlap of two shapes' Gaussians at corresponding
    landmarks, :math:`\int \mathcal{N}(x; u_a, \sigma^2) \mathcal{N}(x; v_a, \sigma^2)\, dx
    = \mathcal{N}(u_a - v_a; 0, 2\sigma^2)`, is then exactly the
    density of the difference of two corresponding landmarks under the model, so displacements
    of the size the population shows are weighed as typical, larger ones as signal.
    Position and orientation are not landmark noise: the shapes are first superimposed rigidly
    (:func:`~shapelib.pose_align`: generalised Procrustes with rotations and
    translations, sizes kept), which fits
    ``d(d + 1)/2`` pose parameters per shape, so the denominator is
    ``(N − 1) K d − N d(d + 1)/2`` (without it σ̂² of aligned shapes is low by ``d(d + 1)/(2 K d)``:
    3 % for 50 planar landmarks). Shapes already scaled to one size (:func:`shapelib.to_centroid_size`)
    have lost one more degree of freedom each: 1 % low for 50 planar landmarks.

Held-out prediction (``predictive_sigma2``)
    The σ² at which one shape's mixture best predicts another shape's landmarks: maximise the
    mean log-likelihood

    .. math::

        \ell(s^2) = \frac{1}{K} \sum_{a} \log p(x_{ia} \mid x_j, s^2), \qquad i \ne j

    (eq. 5, the mixture of shape ``j`` with variance :math:`s^2`), and report :math:`s^2/2`: both shapes are noisy, so
    the best ``s²`` is the variance of a landmark difference, ``2σ²``. It does not use the
    landmark correspondence (any landmark of ``j`` may explain ``x_ia``), so once the Gaussians
    of neighbouring landmarks overlap it attributes part of the scatter to the wrong component
    and comes out wrong: measured on 60 noisy copies of a 30-landmark circle, within 1 % of the
    truth at σ = 0.05–0.1 landmark spacings, 5–7 % high at 0.2–0.3, then low by 17 % at 0.5,
    40 % at one spacing and half at two (the scatter rule: within its 2.4 % standard error
    throughout; ``tests/test_sigma2.py``). A check on the scatter rule where σ is small, nothing
    more.

Both are pure functions of an ``(N, K, d)`` array.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import logsumexp

from .._validate import as_shapes, check_positive_int
from .procrustes import pose_align

__all__ = ["scatter_sigma2", "predictive_sigma2"]


def scatter_sigma2(shapes, *, superimpose: bool = True):
    r"""Maximum-likelihood σ² (unbiased denominator) of the landmark scatter around the mean shape.

    The generative reading of eq. (5) of [1]_: landmark ``a`` of shape ``i`` is
    :math:`x_{ia} = \mu_a + \varepsilon_{ia}`, :math:`\varepsilon \sim \mathcal{N}(0, \sigma^2 I_d)`, so

    .. math::

        \hat\sigma^2 = \frac{1}{\mathrm{df}} \sum_{i,a} |x_{ia} - \bar x_a|^2, \qquad
        \mathrm{df} = (N - 1) K d - N \frac{d(d + 1)}{2}, \qquad
        \operatorname{se}(\hat\sigma^2) = \hat\sigma^2 \sqrt{2 / \mathrm{df}},

    the pose term counted only with ``superimpose``.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        Shapes in landmark correspondence, N ≥ 2.
    superimpose : bool, default True
        First superimpose them rigidly (:func:`shapelib.pose_align`) and count the pose
        parameters in the denominator (module docstring); ``False``: the scatter as given.

    Returns
    -------
    sigma2 : float
        :math:`\hat\sigma^2`.
    standard_error : float
        :math:`\hat\sigma^2 \sqrt{2/\mathrm{df}}` (σ̂² is σ² times a χ² with df degrees of freedom
        over df).
    per_landmark : ndarray, shape (K,)
        The same for each landmark alone (:math:`\sum_i |x_{ia} - \bar x_a|^2` over its share
        df / K): how far the isotropic, equal-σ model of eq. (5) is from the data.

    Raises
    ------
    ValueError
        Fewer than two shapes, too few landmarks to estimate anything beyond the pose, or
        every shape identical (no scatter to measure).

    See Also
    --------
    shapelib.estimate_sigma2 : The library's σ² rule, built on this.
    shapelib.geometry.sigma2.predictive_sigma2 : The held-out prediction estimator.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    >>> import numpy as np
    >>> from shapelib.geometry.sigma2 import scatter_sigma2
    >>> rng = np.random.default_rng(1)
    >>> t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    >>> shapes = 3.0 * np.c_[np.cos(t), np.sin(t)] + 0.5 * rng.standard_normal((20, 12, 2))
    >>> s2, se, per_landmark = scatter_sigma2(shapes)
    >>> round(s2, 2), per_landmark.shape
    (0.2, (12,))
    """
    x = as_shapes(shapes, name="shapes", min_shapes=2)
    n, k, d = x.shape
    df = (n - 1) * k * d
    if superimpose:
        x, _ = pose_align(x)
        df -= n * d * (d + 1) // 2
    if df < 1:
        raise ValueError(f"shapes: {n} shapes of {k} landmarks in {d}-D leave no degrees of freedom once their "
                         "pose is fitted; sigma2 cannot be estimated from them")
    dev = x - x.mean(axis=0)
    per_landmark = np.einsum("nkd,nkd->k", dev, dev) / (df / k)
    s2 = float(per_landmark.mean())
    if not s2 > 0:
        raise ValueError("shapes: every shape is the same, so the landmark scatter (and sigma2 from it) is 0")
    return s2, s2 * float(np.sqrt(2.0 / df)), per_landmark


def predictive_sigma2(shapes, *, partners: int | None = None, seed: int = 0) -> float:
    r"""σ² at which one shape's mixture best predicts another shape's landmarks (module docstring).

    Maximises the mean held-out log-likelihood of eq. (5) of [1]_ over :math:`s^2`,

    .. math::

        \hat s^2 = \arg\max_{s^2} \frac{1}{|P| K} \sum_{(i, j) \in P} \sum_{a}
        \log p(x_{ia} \mid x_j, s^2),

    and returns :math:`\hat s^2 / 2` (both shapes are noisy, so :math:`\hat s^2` is the variance of
    a landmark difference), corrected for the pose parameters the superimposition fitted.

    Parameters
    ----------
    shapes : array_like, shape (N, K, d)
        Shapes, N ≥ 2 (superimposed rigidly first, :func:`shapelib.pose_align`; the landmark
        correspondence is used for that only).
    partners : int, optional
        Shapes ``j`` each shape ``i`` is predicted from (drawn at random without replacement);
        default all the others up to 2 million landmark pairs in all.
    seed : int, default 0
        Seed of the draw of partners.

    Returns
    -------
    float
        :math:`\hat s^2 / 2` times :math:`K d / (K d - d(d + 1)/2)` for the pose parameters the
        superimposition fitted (as :func:`~shapelib.geometry.sigma2.scatter_sigma2`).

    Raises
    ------
    ValueError
        Fewer than two shapes, a non-positive ``partners``, or all landmarks coincident.

    See Also
    --------
    shapelib.geometry.sigma2.scatter_sigma2 : The estimator the library uses.
    shapelib.estimate_sigma2 : Either estimator with a summary.

    References
    ----------
    .. [1] A. M. Peter and A. Rangarajan, "Information geometry for landmark shape analysis: unifying shape
       representation and deformation", *IEEE Transactions on Pattern Analysis and Machine Intelligence*
       31(2), 337–350, 2009.

    Examples
    --------
    Where σ is small against the landmark spacing the two estimators agree:

    >>> import numpy as np
    >>> from shapelib.geometry.sigma2 import predictive_sigma2
    >>> rng = np.random.default_rng(1)
    >>> t = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    >>> shapes = 3.0 * np.c_[np.cos(t), np.sin(t)] + 0.1 * rng.standard_normal((20, 12, 2))
    >>> round(predictive_sigma2(shapes), 3)
    0.008
    """
    x, _ = pose_align(as_shapes(shapes, name="shapes", min_shapes=2))
    n, k, d = x.shape
    most = n - 1
    if partners is None:
        partners = int(np.clip(2 ** 21 // (n * k * k), 1, most))
    partners = min(check_positive_int(partners, name="partners"), most)
    rng = np.random.default_rng(seed)
    i = np.repeat(np.arange(n), partners)
    j = np.concatenate([(a + 1 + rng.choice(most, size=partners, replace=False)) % n for a in range(n)])
    diff = x[i][:, :, None, :] - x[j][:, None, :, :]
    sq = np.einsum("pabd,pabd->pab", diff, diff)  # |x_ia − x_jb|²
    positive = sq[sq > 0]
    if positive.size == 0:
        raise ValueError("shapes: all landmarks coincide, so no sigma2 can be estimated from them")

    def neg_loglik(t):
        s2 = np.exp(t)
        ll = logsumexp(-sq / (2 * s2), axis=2) - 0.5 * d * np.log(2 * np.pi * s2) - np.log(k)
        return -float(ll.mean())

    lo, hi = np.log(positive.min() / 100), np.log(sq.max() * 10)
    res = minimize_scalar(neg_loglik, bounds=(lo, hi), method="bounded", options={"xatol": 1e-8})
    pose = k * d / (k * d - d * (d + 1) / 2) if k * d > d * (d + 1) / 2 else 1.0  # as scatter_sigma2's df
    return float(np.exp(res.x)) / 2 * pose
