"""The arm's links as rigid bodies for the URDF (a simulator's dynamics): each link's mass,
centre of mass and inertia tensor, from the model file's [masses] with a simple solid for
each part's shape. SI units (kg, m, kg m^2), each link in its URDF frame: the joint at the
origin, the link hanging along -z at zero angle.

Shapes: an AX-12A is a solid box of its e-manual's 32 x 50 x 40 mm; a link's brackets a
solid rod of the link's length and the URDF's visual radius, centred on their centre of
mass; the tool a solid ball. The same solids are the links' collision shapes.
"""
from __future__ import annotations

from dataclasses import dataclass

AX12_BOX_M = (0.032, 0.050, 0.040)   # x, y, z
ROD_RADIUS_M = 0.010
TOOL_RADIUS_M = 0.015


@dataclass(frozen=True)
class Part:
    kg: float
    centre: tuple[float, float, float]     # m, in the link's frame
    inertia: tuple[float, float, float]    # kg m^2 about its own centre, the link's axes (principal)
    geometry: str                          # its shape as a URDF geometry (the link's collision)


@dataclass(frozen=True)
class Body:
    kg: float
    centre: tuple[float, float, float]
    inertia: tuple[tuple[float, float, float], ...]   # 3 x 3 about the centre


def box(kg: float, size: tuple[float, float, float], centre) -> Part:
    a, b, c = size
    return Part(kg, tuple(centre), (kg * (b * b + c * c) / 12, kg * (a * a + c * c) / 12, kg * (a * a + b * b) / 12),
                f'<box size="{a:.6g} {b:.6g} {c:.6g}"/>')


def rod(kg: float, length: float, radius: float, centre) -> Part:
    """A solid cylinder along z."""
    across = kg * (3 * radius * radius + length * length) / 12
    return Part(kg, tuple(centre), (across, across, kg * radius * radius / 2),
                f'<cylinder radius="{radius:.6g}" length="{length:.6g}"/>')


def ball(kg: float, radius: float, centre) -> Part:
    i = 2 * kg * radius * radius / 5
    return Part(kg, tuple(centre), (i, i, i), f'<sphere radius="{radius:.6g}"/>')


def combine(parts) -> Body:
    """One rigid body of the parts: the total mass, its centre, and the inertia about that
    centre (each part's own moved there by the parallel axis theorem)."""
    kg = sum(p.kg for p in parts)
    centre = tuple(sum(p.kg * p.centre[k] for p in parts) / kg for k in range(3))
    inertia = [[0.0] * 3 for _ in range(3)]
    for p in parts:
        d = [p.centre[k] - centre[k] for k in range(3)]
        dd = sum(v * v for v in d)
        for i in range(3):
            for j in range(3):
                inertia[i][j] += p.kg * ((dd if i == j else 0.0) - d[i] * d[j]) + (p.inertia[i] if i == j else 0.0)
    return Body(kg, centre, tuple(tuple(row) for row in inertia))


def link_parts(m) -> dict[str, list[Part]]:
    """Each URDF link's parts (m: the model): joint 1's servo on the base (on the drone), the
    shoulder servo on joint 1's link at the shoulder, the elbow servo at the upper arm's end."""
    g, mm = (lambda grams: grams / 1000.0), (lambda v: v / 1000.0)
    ms = m.masses
    L1, L2, L3 = mm(m.L1), mm(m.L2), mm(m.L3)
    servo = lambda centre: box(g(ms.servo), AX12_BOX_M, centre)
    return {
        "arm_base": [servo((0.0, 0.0, 0.0))],
        "arm_turret": [servo((0.0, 0.0, -L1))],
        "upper_arm": [rod(g(ms.upper_arm), L2, ROD_RADIUS_M, (0.0, 0.0, -mm(ms.upper_arm_com))),
                      servo((0.0, 0.0, -L2))],
        "forearm": [rod(g(ms.forearm), L3, ROD_RADIUS_M, (0.0, 0.0, -mm(ms.forearm_com))),
                    ball(g(ms.end_effector), TOOL_RADIUS_M, (0.0, 0.0, -mm(ms.end_effector_com)))],
    }


def link_bodies(m) -> dict[str, Body]:
    return {name: combine(parts) for name, parts in link_parts(m).items()}
