"""Geometry kernels: small pure functions of arrays (vertices (V, 3), faces (F, 3) int).

The bottom of the stack: shared by the phantoms (`phantoms/`), the methods (`methods/`) and the metrics (`bench/`);
nothing here imports any of them.
"""

from .curvature import paraboloid_curvature, radius_curvature
from .errors import InputError
from .levelset import newton_project
from .mesh import (
    MAX_NEIGHBORS,
    face_areas,
    face_normals,
    lumped_vertex_areas,
    one_ring,
    padded_from_pairs,
    radius_neighbors,
    sample_surface,
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
from .topology import (
    connected_components,
    directed_edge_repeats,
    edge_face_counts,
    edges_unique,
    euler_characteristic,
    face_edge_keys,
    face_edges,
    genus,
    is_closed,
    is_manifold,
    is_oriented,
)

__all__ = [
    "InputError",
    "face_normals", "face_areas", "vertex_normals", "lumped_vertex_areas", "edges_unique",
    "one_ring", "radius_neighbors", "MAX_NEIGHBORS", "padded_from_pairs", "paraboloid_curvature", "radius_curvature",
    "MeshOperators", "cotangent_stiffness", "lumped_mass", "face_gradient", "gradient_operator", "divergence",
    "jacobi_cg", "fibonacci_sphere",
    "face_edge_keys", "face_edges", "edge_face_counts", "directed_edge_repeats", "is_closed", "is_manifold",
    "is_oriented", "euler_characteristic", "genus", "connected_components", "sample_surface", "newton_project",
]
