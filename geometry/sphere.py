"""The initial surface: a triangulated sphere from a Fibonacci lattice (docs/METHOD.md, "Initial surface").

``fibonacci_sphere()`` with its defaults gives the paper's Γ0: radius 2, 1,896 vertices and 3,788
triangles (a closed convex triangulation of V points on a sphere has exactly 2V − 4 faces).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

__all__ = ["fibonacci_points", "fibonacci_sphere", "PAPER_SPHERE_VERTICES", "PAPER_SPHERE_RADIUS"]

#: the paper's initial surface: 1,896 vertices, 3,788 triangles, radius 2
PAPER_SPHERE_VERTICES = 1896
PAPER_SPHERE_RADIUS = 2.0


def fibonacci_points(n: int) -> np.ndarray:
    """``n`` unit vectors on a Fibonacci (golden-angle) spiral, shape (n, 3).

    Points sit at heights z_k = 1 − (2k + 1)/n (k = 0..n−1), so no point is a pole and the lattice is
    nearly uniform in area.
    """
    n = int(n)
    if n < 4:
        raise ValueError(f"a sphere needs at least 4 points; got {n}")
    k = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * k + 1.0) / n
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    golden = np.pi * (3.0 - np.sqrt(5.0))
    theta = golden * k
    return np.column_stack([r * np.cos(theta), r * np.sin(theta), z])


def fibonacci_sphere(n: int = PAPER_SPHERE_VERTICES, radius: float = PAPER_SPHERE_RADIUS,
                     center=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """A closed, outward-oriented triangulated sphere: ``(vertices (n, 3), faces (2n − 4, 3))``.

    The faces are the convex hull of the Fibonacci lattice, each ordered so that its right-hand normal
    points away from the centre.
    """
    radius = float(radius)
    if not (np.isfinite(radius) and radius > 0):
        raise ValueError(f"sphere radius must be positive; got {radius}")
    c = np.asarray(center, dtype=np.float64).reshape(3)
    u = fibonacci_points(n)
    faces = ConvexHull(u).simplices.astype(np.int64)
    # orient outward: on a unit sphere centred at 0, the face normal must point along the centroid
    a, b, d = u[faces[:, 0]], u[faces[:, 1]], u[faces[:, 2]]
    flip = np.einsum("ij,ij->i", np.cross(b - a, d - a), a + b + d) < 0
    faces[flip] = faces[flip][:, ::-1]
    if len(faces) != 2 * len(u) - 4:  # pragma: no cover - would need four co-circular lattice points
        raise RuntimeError(f"convex hull of {len(u)} Fibonacci points has {len(faces)} faces, not {2 * len(u) - 4}")
    return radius * u + c, faces
