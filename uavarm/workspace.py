"""`uavarm workspace`: the arm's reachable region, side and top views.

Joint space is sampled on a grid a little past the travel limits; each joint vector's end
effector comes from the model's forward kinematics and its class from the model's own
predicates (model/kinematics.py joint_limits_ok, model/collision.py body_clear and
legs_clear), lambdified, so the picture follows the model file and hard-codes nothing:
valid, outside the joint limits, in the body, or at a landing leg.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import sympy as sp

from .model import collision, config, kinematics

CLASSES = ("valid", "joint limit", "body", "leg")
COLOURS = {"valid": "tab:green", "joint limit": "0.8", "body": "tab:red", "leg": "tab:orange"}


def sample(m: config.Model, steps=(73, 61, 61), past_deg: float = 20.0):
    """(points (n, 3) mm, joint-3 points, class index (n,)) over a joint grid that runs
    past_deg beyond each limit (clipped to +-180)."""
    axes = [np.radians(np.linspace(max(l.min_deg - past_deg, -180), min(l.max_deg + past_deg, 180), n))
            for l, n in zip(m.limits, steps)]
    q = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    j3_expr, ee_expr = kinematics.fk_points(m)
    qs = kinematics.JOINT_SYMBOLS
    f_ee = sp.lambdify(qs, list(ee_expr), modules="numpy")
    f_j3 = sp.lambdify(qs, list(j3_expr), modules="numpy")
    cols = lambda f: np.stack([np.broadcast_to(v, q[:, 0].shape) for v in f(q[:, 0], q[:, 1], q[:, 2])], axis=-1)
    ee, j3 = cols(f_ee), cols(f_j3)
    g = kinematics.fk_geometry(m)
    limits = sp.lambdify(qs, kinematics.joint_limits_ok(m, qs), modules="numpy")
    body = sp.lambdify(qs, collision.body_clear(m, g), modules="numpy")
    legs = sp.lambdify(qs, collision.legs_clear(m, g), modules="numpy")
    a = (q[:, 0], q[:, 1], q[:, 2])
    cls = np.zeros(len(q), dtype=int)
    legs_ok = np.broadcast_to(legs(*a), cls.shape)
    body_ok = np.broadcast_to(body(*a), cls.shape)
    cls[~legs_ok] = 3
    cls[~body_ok] = 2
    cls[~np.broadcast_to(limits(*a), cls.shape)] = 1
    return ee, j3, cls


def raster(u, v, cls, extent, pixels=240):
    """A class image: each pixel shows the most permissive class sampled in it (valid over
    leg over body over joint limit), -1 where nothing is reached."""
    (u0, u1), (v0, v1) = extent
    iu = np.clip(((u - u0) / (u1 - u0) * pixels).astype(int), 0, pixels - 1)
    iv = np.clip(((v - v0) / (v1 - v0) * pixels).astype(int), 0, pixels - 1)
    rank = np.array([3, 0, 1, 2])[cls]                # valid 3 > leg 2 > body 1 > limit 0
    img = np.full(pixels * pixels, -1)
    np.maximum.at(img, iv * pixels + iu, rank)
    return img.reshape(pixels, pixels)


def plot(m: config.Model, out: Path, side_steps=(25, 181, 181), top_steps=(241, 71, 71)) -> dict[str, int]:
    """Writes the PNG; returns how many sampled poses (of the top view's grid) fell in each
    class. The side view samples joints 2 and 3 finely, the top view joint 1."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch, Wedge
    ee_s, _, cls_s = sample(m, side_steps)
    ee, _, cls = sample(m, top_steps)
    reach = (m.L1 + m.L2 + m.L3) * 1.1
    order = ["joint limit", "body", "leg", "valid"]           # rank 0..3
    cmap = ListedColormap([COLOURS[n] for n in order])
    counts = {name: int((cls == k).sum()) for k, name in enumerate(CLASSES)}
    fig, (side, top) = plt.subplots(1, 2, figsize=(13, 6.5))
    for ax, (u, v), c, extent in (
            (side, (np.hypot(ee_s[:, 0], ee_s[:, 1]), ee_s[:, 2]), cls_s, ((0, reach), (-reach, reach * 0.5))),
            (top, (ee[:, 0], ee[:, 1]), cls, ((-reach, reach), (-reach, reach)))):
        img = np.ma.masked_less(raster(u, v, c, extent, pixels=200), 0)
        ax.imshow(img, origin="lower", extent=(*extent[0], *extent[1]), cmap=cmap, vmin=-0.5, vmax=3.5,
                  interpolation="nearest")
        ax.set_aspect("equal")
    side.axhspan(m.body_z, reach * 0.5, color="tab:red", alpha=0.10)
    side.axhline(m.body_z, color="tab:red", lw=1)
    side.axvline(m.leg_distance, color="tab:orange", ls="--", lw=1)
    side.set_xlabel("horizontal distance from the base axis, mm")
    side.set_ylabel("z (base frame, up), mm")
    side.set_title("side view: every joint-1 angle folded onto one plane")
    # the arm's plane at joint angle a points along azimuth -a (x = u cos a, y = -u sin a)
    for angle in m.leg_angles:
        for az in (-angle, 180 - angle):
            top.add_patch(Wedge((0, 0), reach, az - m.leg_half_width, az + m.leg_half_width,
                                width=reach - m.leg_distance, color="tab:orange", alpha=0.15))
        top.plot([0, reach * math.cos(math.radians(-angle))], [0, reach * math.sin(math.radians(-angle))],
                 color="tab:orange", lw=1)
    top.add_patch(plt.Circle((0, 0), m.leg_distance, fill=False, ls="--", color="tab:orange", lw=1))
    top.set_xlabel("x, mm")
    top.set_ylabel("y, mm")
    top.set_title("top view: legs (lines) and their no-go zones (shaded)")
    handles = [Patch(color=COLOURS[n], label=f"{n} ({counts[n]} poses)") for n in reversed(order)]
    handles += [Patch(color="tab:red", alpha=0.2, label=f"body: z >= {m.body_z:g} mm"),
                Patch(color="tab:orange", alpha=0.3, label=f"leg: within {m.leg_half_width:g} deg of a leg, "
                                                            f"beyond {m.leg_distance:g} mm")]
    fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=9)
    lims = ", ".join(f"theta{j + 1} {l.min_deg:g}..{l.max_deg:g}" for j, l in enumerate(m.limits))
    fig.suptitle(f"End-effector reach, {m.path.name} (joint limits {lims} deg);\n"
                 f"each pixel: the best class of the poses reaching it")
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return counts
