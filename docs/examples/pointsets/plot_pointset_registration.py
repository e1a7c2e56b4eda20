"""
Registering shapes without landmarks
====================================

A fish outline from the Chui–Rangarajan benchmark registered onto a copy that is deformed and
turned upside down: the pose search over every rotation finds the orientation, EM estimates σ²
and the correspondences, and the deformation is fitted through the mixture's metric kernel.
Coherent Point Drift, which starts from the pose as given, is drawn beside it.
"""

import matplotlib.pyplot as plt
import numpy as np

import shapelib as sl
from shapelib.datasets import load_tps_rpm_case

case = load_tps_rpm_case("fish_rot_5", sample=1)
x1, y2a, truth = case["x1"], case["y2a"], case["y2"]
n = len(truth)

res = sl.register(x1, y2a)
print(res.summary())
err = np.mean(np.linalg.norm(res.points[:n] - truth, axis=1))

fig, axes = plt.subplots(1, 3, figsize=(11, 3.8))
axes[0].plot(*x1.T, ".", color="tab:blue", ms=4, label="source")
axes[0].plot(*y2a.T, ".", color="0.5", ms=4, label="target")
axes[0].set_title("input")
axes[0].legend(fontsize=8)
axes[1].plot(*y2a.T, ".", color="0.5", ms=4)
axes[1].plot(*res.rigid_points.T, ".", color="tab:blue", ms=3)
axes[1].set_title(f"pose: {res.pose.angle:.0f}°")
axes[2].plot(*y2a.T, ".", color="0.5", ms=4)
axes[2].plot(*res.points.T, ".", color="tab:red", ms=3)
for a, b in zip(res.points[:n], truth):
    axes[2].plot([a[0], b[0]], [a[1], b[1]], "k-", lw=0.4)
axes[2].set_title(f"registered: mean error {err:.4f}")
try:
    from pycpd import DeformableRegistration

    def normalise(a):
        m = a.mean(0)
        s = np.sqrt(np.sum((a - m) ** 2) / len(a))
        return (a - m) / s, m, s

    yn, my, sy = normalise(y2a)
    cpd, _ = DeformableRegistration(X=yn, Y=normalise(x1)[0]).register()
    cpd = cpd * sy + my
    axes[2].plot(*cpd.T, "x", color="tab:green", ms=3, label="CPD")
    axes[2].legend(fontsize=8)
except ImportError:  # pycpd: pip install 'shapelib[bench]'
    pass
for ax in axes:
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
fig.tight_layout()
plt.show()
