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


def from_vectors(axis_angles) -> np.ndarray:
    """from_vector of each row of an (n, 3) array: (n, 3, 3)."""
    v = np.asarray(axis_angles, dtype=float).reshape(-1, 3)
    angle = np.linalg.norm(v, axis=1)
    turning = angle >= 1e-12
    k = np.zeros_like(v)
    k[turning] = v[turning] / angle[turning, None]
    K = np.zeros((len(v), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -k[:, 2], k[:, 1], -k[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = k[:, 2], -k[:, 1], k[:, 0]
    s, c = np.where(turning, np.sin(angle), 0.0), np.where(turning, 1.0 - np.cos(angle), 0.0)
    return np.eye(3) + s[:, None, None] * K + c[:, None, None] * (K @ K)


def product(matrices: np.ndarray) -> np.ndarray:
    """matrices[0] @ matrices[1] @ ... (identity for none), neighbours multiplied pairwise."""
    m = np.asarray(matrices, dtype=float)
    if len(m) == 0:
        return np.eye(3)
    while len(m) > 1:
        odd = m[-1:] if len(m) % 2 else m[:0]
        m = np.concatenate([m[0:len(m) - 1:2] @ m[1::2], odd])
    return m[0]
