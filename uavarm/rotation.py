"""Rotation matrices from rotation vectors, for the host tools that turn a board by hand
(the gyro-scale calibration's integration, the simulated board's turns)."""
from __future__ import annotations

import math

import numpy as np


def from_vector(axis_angle) -> np.ndarray:
    """Rodrigues: the rotation matrix of a rotation vector (rad)."""
    v = np.asarray(axis_angle, dtype=float)
    angle = float(np.linalg.norm(v))
    if angle < 1e-12:
        return np.eye(3)
    k = v / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K
