"""Mesh-backed phantoms: any closed triangle mesh as a phantom whose ground truth is the mesh itself.

* :mod:`.phantom` – :class:`MeshPhantom` (validation, normalisation, truth, curvature, creases) and
  :func:`load_mesh`;
* :mod:`.index` – the search index: certified exact closest-point queries and the pseudonormal sign;
* :mod:`.grid_sdf` – the signed distance on a grid (exact narrow band + closest-triangle propagation), with
  its compiled kernels in :mod:`.grid_kernels`;
* :mod:`.closest` – the point–segment distance and the generalised winding number (the closest point on a
  triangle: :mod:`geometry.closest`).
"""

from .closest import winding_number
from .grid_sdf import signed_distance_grid
from .index import TriangleIndex
from .phantom import TARGET_RADIUS, MeshPhantom, load_mesh

__all__ = ["MeshPhantom", "load_mesh", "TARGET_RADIUS", "TriangleIndex", "signed_distance_grid",
           "winding_number"]
