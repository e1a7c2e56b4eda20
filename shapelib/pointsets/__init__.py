"""Shapes without landmarks: point sets of any size, compared and registered by the information geometry.

A point set is an ``(n, d)`` array (d = 2 or 3) of any number of points in no order; it is the
equal-weight isotropic mixture of eq. (5) with one component per point. Modules:

* ``shapelib.pointsets.checks``: input checks (:func:`as_point_set`, :func:`as_point_sets`);
* ``shapelib.pointsets.density``: closed-form and quadrature density distances between sets of
  different sizes, with gradients w.r.t. the points;
* ``shapelib.pointsets.pose``: the pose search over every rotation (:func:`align`);
* ``shapelib.pointsets.em``: σ² (and the means of a compact mixture) from the points (:func:`fit_mixture`);
* ``shapelib.pointsets.registration``: registration, rigid to non-rigid, by the information
  geometry (:func:`register`; many pairs at once, batched on JAX: :func:`register_many`).
"""

from .checks import as_point_set, as_point_sets
from .density import bhattacharyya_affinity, density_distance, density_inner, hellinger_sq, l2_distance_sq
from .em import EMWarning, MixtureFit, fit_mixture
from .pose import Pose, PoseSearchWarning, align
from .registration import RegistrationResult, RegistrationWarning, register
from ._batch import register_many

__all__ = ["as_point_set", "as_point_sets", "bhattacharyya_affinity", "density_distance", "density_inner",
           "hellinger_sq", "l2_distance_sq", "align", "Pose", "PoseSearchWarning", "fit_mixture", "MixtureFit",
           "EMWarning", "register", "register_many", "RegistrationResult", "RegistrationWarning"]
