"""`uavarm workspace`: the arm's reachable region as a figure (PNG and PDF), side and top views.

Exact per point, not sampled poses: in the arm's vertical plane each point (u, z) has at
most two joint pairs (q2, q3) that reach it (the two elbows of the planar two-link arm below
the shoulder: |q3| from the law of cosines, q2 from the bearing less the elbow's offset).
Each candidate is judged by the model's own predicates (model/kinematics.py
joint_limits_ok, model/collision.py body_clear and legs_clear, lambdified), so the figure
follows the model file and hard-codes nothing: reachable and valid, within the joint limits
but in the body, within them but beyond a leg, or out of reach. The top view is the side
view's horizontal extent turned about joint 1's axis: per direction the plane's joint-1
angle (or the opposite one, reaching over with joint 2 the other way), its limits and
whether a leg blocks that plane.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import sympy as sp

from ..model import collision, config, kinematics

CLASSES = ("out of reach", "valid", "body", "leg")
COLOURS = {"out of reach": "white", "valid": "#4c9a2a", "body": "#d9534f", "leg": "#f0ad4e"}
MM_PER_PIXEL = 0.5


class Predicates:
    """The model's limit, body and leg predicates as numpy functions of (q1, q2, q3)."""

    def __init__(self, m: config.Model):
        qs = kinematics.JOINT_SYMBOLS
        g = kinematics.fk_geometry(m)
        f = lambda expr: sp.lambdify(qs, expr, modules="numpy")
        self._limits = f(kinematics.joint_limits_ok(m, qs))
        self._body = f(collision.body_clear(m, g))
        self._legs = f(collision.legs_clear(m, g))
        self._near = f(collision.near_leg(m, g))
        u3, z3, u, z = kinematics.fk_in_plane(m)
        self.in_plane = f([u3, z3, u, z])

    @staticmethod
    def _each(fn, q1, q2, q3):
        q1, q2, q3 = np.broadcast_arrays(np.asarray(q1, float), np.asarray(q2, float), np.asarray(q3, float))
        return np.broadcast_to(fn(q1, q2, q3), q1.shape)

    def limits(self, q1, q2, q3):
        return self._each(self._limits, q1, q2, q3)

    def body(self, q1, q2, q3):
        return self._each(self._body, q1, q2, q3)

    def legs(self, q1, q2, q3):
        return self._each(self._legs, q1, q2, q3)

    def near_leg(self, q1):
        return self._each(self._near, q1, 0.0, 0.0)


def plane_ik(m: config.Model, u, z):
    """The two (q2, q3) reaching (u, z) in the arm's plane (u along the plane, z up, mm),
    elbow one way then the other; NaN where the point is beyond reach."""
    du, dz = np.asarray(u, float), np.asarray(z, float) + m.L1          # from the shoulder
    c3 = (du * du + dz * dz - m.L2 ** 2 - m.L3 ** 2) / (2 * m.L2 * m.L3)
    q3 = np.arccos(np.where(np.abs(c3) <= 1.0, c3, np.nan))
    bearing = np.arctan2(du, -dz)                                        # from straight down
    out = []
    for sign in (1.0, -1.0):
        s3 = sign * q3
        q2 = bearing - np.arctan2(m.L3 * np.sin(s3), m.L2 + m.L3 * np.cos(s3))
        out.append((np.angle(np.exp(1j * q2)), s3))                     # wrapped to (-pi, pi]
    return out


def classify_plane(m: config.Model, pred: Predicates, q1: float, u, z) -> np.ndarray:
    """Class index (CLASSES) of each point of the plane at joint-1 angle q1: valid if one of
    its two poses passes every predicate; else body or leg if a pose within the limits fails
    only that; else out of reach."""
    cls = np.zeros(np.shape(u), dtype=int)
    found = {k: np.zeros(np.shape(u), dtype=bool) for k in ("valid", "body", "leg")}
    for q2, q3 in plane_ik(m, u, z):
        ok = np.isfinite(q3)
        q2s, q3s = np.where(ok, q2, 0.0), np.where(ok, q3, 0.0)
        within = ok & pred.limits(q1, q2s, q3s)
        body, legs = pred.body(q1, q2s, q3s), pred.legs(q1, q2s, q3s)
        found["valid"] |= within & body & legs
        found["body"] |= within & ~body
        found["leg"] |= within & body & ~legs
    for name in ("leg", "body", "valid"):           # the most permissive class wins
        cls[found[name]] = CLASSES.index(name)
    return cls


def reach(m: config.Model, pred: Predicates, q1: float, extent: float) -> tuple[float, float, float]:
    """In the plane at q1, on a grid of MM_PER_PIXEL: the largest horizontal distance of a
    valid point on its own side (joint 2 forward) and on the other, and the lowest valid z
    (mm; 0 where none)."""
    u = np.arange(-extent, extent + MM_PER_PIXEL, MM_PER_PIXEL)
    z = np.arange(-extent, m.body_z + MM_PER_PIXEL, MM_PER_PIXEL)
    uu, zz = np.meshgrid(u, z)
    valid = classify_plane(m, pred, q1, uu, zz) == CLASSES.index("valid")
    cols, rows = valid.any(axis=0), valid.any(axis=1)
    ahead, behind, low = u[cols & (u >= 0)], u[cols & (u <= 0)], z[rows]
    return (float(ahead.max()) if len(ahead) else 0.0, float(-behind.min()) if len(behind) else 0.0,
            float(low.min()) if len(low) else 0.0)


def leg_free_angle(m: config.Model, pred: Predicates) -> float:
    """A joint-1 angle within the limits whose plane no leg blocks (the side view's)."""
    for deg in np.arange(0.0, 180.0, 0.5):
        for q1 in (math.radians(deg), -math.radians(deg)):
            if pred.limits(q1, 0.0, 0.0) and not pred.near_leg(q1):
                return q1
    raise ValueError("every joint-1 angle within the limits is beside a leg")


def top_view(m: config.Model, pred: Predicates, x, y, reach_free, reach_leg) -> np.ndarray:
    """Class of each point (x, y) seen from above: valid within the reach of the plane that
    points there (directly, or over the top with joint 2 the other way); leg where only a
    leg keeps the arm short of it; out of reach otherwise."""
    r, azimuth = np.hypot(x, y), np.arctan2(y, x)
    cls = np.zeros(np.shape(x), dtype=int)
    # the plane at joint angle a points along azimuth -a (u along (cos a, -sin a))
    for q1, side in ((-azimuth, 0), (math.pi - azimuth, 1)):
        q1 = np.angle(np.exp(1j * q1))
        within = pred.limits(q1, 0.0, 0.0)
        near = pred.near_leg(q1)
        short = np.where(near, reach_leg[side], reach_free[side])
        cls[within & (r <= short)] = CLASSES.index("valid")
        blocked = within & near & (r > reach_leg[side]) & (r <= reach_free[side])
        cls[blocked & (cls != CLASSES.index("valid"))] = CLASSES.index("leg")
    return cls


def plot(m: config.Model, out: Path) -> dict[str, float]:
    """Writes out (PNG) and its PDF beside it; returns the figures it shows (mm): horizontal
    reach ahead and behind, beside a leg, and the lowest point."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    pred = Predicates(m)
    extent = (m.L1 + m.L2 + m.L3) * 1.08
    free = leg_free_angle(m, pred)
    leg_q1 = math.radians(m.leg_angles[0])
    reach_free, reach_leg = reach(m, pred, free, extent), reach(m, pred, leg_q1, extent)
    cmap = ListedColormap([COLOURS[name] for name in CLASSES])
    fig, axes = plt.subplots(1, 3, figsize=(15, 5.4), gridspec_kw={"width_ratios": [1, 1, 1.15]})
    u = np.arange(-extent, extent, MM_PER_PIXEL)
    z = np.arange(-extent, extent * 0.35, MM_PER_PIXEL)
    uu, zz = np.meshgrid(u, z)
    for ax, q1, title in ((axes[0], free, f"side: joint 1 at {math.degrees(free):g} deg (no leg)"),
                          (axes[1], leg_q1, f"side: joint 1 at {m.leg_angles[0]:g} deg (a leg's plane)")):
        cls = classify_plane(m, pred, q1, uu, zz)
        ax.imshow(cls, origin="lower", extent=(u[0], u[-1], z[0], z[-1]), cmap=cmap, vmin=-0.5,
                  vmax=len(CLASSES) - 0.5, interpolation="nearest")
        ax.contour(uu, zz, cls == CLASSES.index("valid"), levels=[0.5], colors="k", linewidths=0.8)
        ax.axhline(m.body_z, color=COLOURS["body"], lw=1.2)
        ax.plot([0], [-m.L1], "k+", ms=8)
        ax.set(title=title, xlabel="distance along the arm's plane, mm (joint 2 forward: +)",
               ylabel="z, mm (up)", aspect="equal")
    xy = np.arange(-extent, extent, MM_PER_PIXEL)
    xx, yy = np.meshgrid(xy, xy)
    top = top_view(m, pred, xx, yy, reach_free, reach_leg)
    ax = axes[2]
    ax.imshow(top, origin="lower", extent=(xy[0], xy[-1], xy[0], xy[-1]), cmap=cmap, vmin=-0.5,
              vmax=len(CLASSES) - 0.5, interpolation="nearest")
    ax.contour(xx, yy, top == CLASSES.index("valid"), levels=[0.5], colors="k", linewidths=0.8)
    for angle in m.leg_angles:                     # the legs, as drawn lines out from the axis
        a = -math.radians(angle)
        ax.plot([m.leg_distance * math.cos(a), extent * math.cos(a)],
                [m.leg_distance * math.sin(a), extent * math.sin(a)], color="0.3", lw=3, solid_capstyle="butt")
    ax.set(title="top: x forward, y left", xlabel="x, mm", ylabel="y, mm", aspect="equal")
    handles = [Patch(facecolor=COLOURS[n], edgecolor="0.5", label=label) for n, label in (
        ("valid", "reachable and valid"), ("body", f"within the joint limits, in the body (z >= {m.body_z:g} mm)"),
        ("leg", f"within the joint limits, beyond a leg ({m.leg_distance:g} mm, +-{m.leg_half_width:g} deg)"))]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=9, frameon=False)
    lims = ", ".join(f"{l.min_deg:g}..{l.max_deg:g}" for l in m.limits)
    fig.suptitle(f"Reachable region of the end effector, {m.path.name}: L1 {m.L1:g}, L2 {m.L2:g}, L3 {m.L3:g} mm; "
                 f"joint limits {lims} deg")
    fig.tight_layout(rect=(0, 0.06, 1, 0.95))
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=150)
    fig.savefig(out.with_suffix(".pdf"))
    plt.close(fig)
    return {"reach": reach_free[0], "reach behind": reach_free[1], "reach beside a leg": reach_leg[0],
            "lowest": reach_free[2]}
