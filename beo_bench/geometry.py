"""Rotations, rigid transforms and symmetry groups.

Rotation matrices act on column vectors (``x' = R @ x``). Symmetry groups use the BOP
toolkit's ``models_info`` form (see :class:`beo_bench.types.Symmetry`).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial.transform import Rotation

from beo_bench.types import Mat3, Mat4, Symmetry

_EZ = np.array([0.0, 0.0, 1.0])


def axis_angle(axis: np.ndarray | list[float], angle: float) -> Mat3:
    """Rotation by ``angle`` radians about ``axis`` (any non-zero length)."""
    a = np.asarray(axis, dtype=np.float64)
    return Rotation.from_rotvec(a / np.linalg.norm(a) * angle).as_matrix()


def rigid(R: Mat3, t: np.ndarray | list[float] | None = None) -> Mat4:
    """4x4 homogeneous transform from a rotation and a translation."""
    T = np.eye(4)
    T[:3, :3] = R
    if t is not None:
        T[:3, 3] = t
    return T


def no_symmetry() -> Symmetry:
    """The trivial group (only the identity)."""
    return {"continuous": [], "discrete": []}


def continuous_symmetry(
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0),
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
    flips: list[Mat3] | None = None,
) -> Symmetry:
    """Continuous symmetry about ``axis`` through ``offset``, plus optional extra
    discrete rotations (e.g. a 180-degree flip of a plain cylinder) about ``offset``."""
    sym: Symmetry = {
        "continuous": [{"axis": list(map(float, axis)), "offset": list(map(float, offset))}],
        "discrete": [],
    }
    for R in flips or []:
        sym["discrete"].append(_about_point(R, offset).tolist())
    return sym


def discrete_symmetry(
    rotations: list[Mat3], offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> Symmetry:
    """A finite group given by its generators' closure; the identity is dropped (BOP form)."""
    group = close_group([np.asarray(R, dtype=np.float64) for R in rotations])
    discrete = [
        _about_point(R, offset).tolist() for R in group if not np.allclose(R, np.eye(3), atol=1e-9)
    ]
    return {"continuous": [], "discrete": discrete}


def cyclic_z(n: int) -> Symmetry:
    """n-fold rotational symmetry about +z (n=1 is the trivial group)."""
    return discrete_symmetry([axis_angle([0, 0, 1], 2 * np.pi / n)] if n > 1 else [])


def close_group(generators: list[Mat3], max_size: int = 64) -> list[Mat3]:
    """All products of ``generators`` (a finite rotation group), identity first."""
    group: list[Mat3] = [np.eye(3)]
    frontier = list(group)
    while frontier:
        new = []
        for A, G in itertools.product(frontier, generators):
            P = G @ A
            if not any(np.allclose(P, Q, atol=1e-8) for Q in group):
                group.append(P)
                new.append(P)
                if len(group) > max_size:
                    raise ValueError("generators do not form a small finite group")
        frontier = new
    return group


def symmetry_transformations(symmetry: Symmetry, max_step_deg: float = 5.0) -> list[Mat4]:
    """Every element of the group as 4x4 transforms, identity included.

    Continuous symmetries are sampled every ``max_step_deg`` degrees and combined with the
    discrete ones, as BOP's ``misc.get_symmetry_transformations`` does.
    """
    discrete = [np.eye(4)] + [np.asarray(T, dtype=np.float64) for T in symmetry["discrete"]]
    continuous = [np.eye(4)]
    for sym in symmetry["continuous"]:
        steps = int(np.ceil(360.0 / max_step_deg))
        for i in range(1, steps):
            R = axis_angle(sym["axis"], 2 * np.pi * i / steps)
            continuous.append(_about_point(R, sym["offset"]))
    return [C @ D for D in discrete for C in continuous]


def _about_point(R: Mat3, p: tuple[float, float, float] | list[float]) -> Mat4:
    """The rotation R about the point p as a 4x4 transform."""
    q = np.asarray(p, dtype=np.float64)
    return rigid(R, q - R @ q)


def super_fibonacci(n: int) -> np.ndarray:
    """(n, 3, 3) rotations spread evenly over SO(3) (Alexa, "Super-Fibonacci Spirals", CVPR
    2022); deterministic."""
    s = np.arange(n) + 0.5
    phi, psi = np.sqrt(2.0), 1.533751168755204288118041
    r, R = np.sqrt(s / n), np.sqrt(1.0 - s / n)
    a, b = 2 * np.pi * s / phi, 2 * np.pi * s / psi
    q = np.stack([r * np.sin(a), r * np.cos(a), R * np.sin(b), R * np.cos(b)], axis=1)
    return Rotation.from_quat(q).as_matrix()


def up_rotation(up: np.ndarray) -> Mat3:
    """The smallest rotation taking +z to the unit vector ``up``."""
    up = np.asarray(up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    axis = np.cross(_EZ, up)
    s, c = np.linalg.norm(axis), float(np.dot(_EZ, up))
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return Rotation.from_rotvec(axis / s * np.arctan2(s, c)).as_matrix()


def yaw_starts(up: np.ndarray, n: int) -> np.ndarray:
    """(n, 3, 3) canonical -> camera rotations that map canonical +z to ``up``, at ``n``
    evenly spaced yaw angles about it."""
    th = 2 * np.pi * np.arange(n) / n
    c, s = np.cos(th), np.sin(th)
    Rz = np.zeros((n, 3, 3))
    Rz[:, 0, 0], Rz[:, 0, 1], Rz[:, 1, 0], Rz[:, 1, 1], Rz[:, 2, 2] = c, -s, s, c, 1.0
    return up_rotation(up) @ Rz


def orthonormalise(R: np.ndarray) -> Mat3:
    """The proper rotation nearest to ``R`` (3, 3) in the Frobenius norm (by SVD)."""
    U, _, Vt = np.linalg.svd(R)
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt
