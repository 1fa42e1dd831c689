"""Geometry kernels: small pure functions of arrays (vertices (V, 3), faces (F, 3) int).

Shared by the methods (``methods/``) and the metrics (``bench/``); nothing here imports either.
"""

from .curvature import paraboloid_curvature
from .errors import InputError
from .mesh import (
    edges_unique,
    face_areas,
    face_normals,
    lumped_vertex_areas,
    one_ring,
    padded_from_pairs,
    radius_neighbors,
    vertex_normals,
)
from .operators import (
    MeshOperators,
    cotangent_stiffness,
    divergence,
    face_gradient,
    gradient_operator,
    jacobi_cg,
    lumped_mass,
)
from .sphere import fibonacci_sphere

__all__ = [
    "InputError",
    "face_normals", "face_areas", "vertex_normals", "lumped_vertex_areas", "edges_unique",
    "one_ring", "radius_neighbors", "padded_from_pairs", "paraboloid_curvature",
    "MeshOperators", "cotangent_stiffness", "lumped_mass", "face_gradient", "gradient_operator", "divergence",
    "jacobi_cg", "fibonacci_sphere",
]
