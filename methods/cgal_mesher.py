"""Peer: CGAL's surface mesher (Boissonnat & Oudot, "Provably good sampling and meshing of surfaces",
Graphical Models 2005; CGAL's 3D Surface Mesh Generation package, Rineau & Yvinec) — Delaunay refinement of
a sample of the surface until every facet meets an angle, a size and an approximation bound.  The mesher
with guarantees: for a smooth surface and small enough bounds the result is a closed 2-manifold homeomorphic
to the surface and close to it in Hausdorff distance.  Through the ``cgal`` SWIG bindings on PyPI
(``CGAL.CGAL_Surface_mesher``).

The surface is the zero set of the volume read as CGAL reads a gray-level image: the bindings mesh an image
file (``Gray_level_image_3``: trilinear interpolation of the voxels, inside where the value exceeds the
iso-value; ``Implicit_surface_3`` over a bounding sphere; ``make_surface_mesh`` with ``Manifold_tag``: the
refinement also goes on until the mesh is a manifold without boundary).  What the adapter does around it:

* writes ``c − φ`` as a float32 INRIMAGE (``.inr``, first axis fastest) in a temporary directory, with the
  iso-value c = max |φ| + 1: CGAL's image is inside where the value is larger, and a point outside the image
  reads 0 < c, outside;
* the image's frame is CGAL's: index · spacing from 0 (CGAL's trilinear interpolation ignores the image's
  translation), so the mesh is moved by the volume's origin afterwards; anisotropic spacing is the image's
  voxel size;
* the bounding sphere is centred on the grid sample of smallest φ (CGAL needs the centre inside; the initial
  points are found by rays from it) and reaches every corner of the grid; the intersection oracle's bisection
  stops at 10⁻⁶ of that radius;
* the criteria are in grid spacings h: ``angle`` (minimum facet angle, degrees; CGAL's usual 30), ``size``
  (upper bound on the radius of the facets' surface Delaunay balls, default 1 h: about marching cubes'
  sampling) and ``distance`` (upper bound on the distance between a facet's circumcentre and the centre of
  its surface Delaunay ball, default 0.1 h);
* reads the mesh back from CGAL's OFF output (coordinates with 6 significant digits: 10⁻⁶ of the grid's
  extent), drops the vertices no facet uses (the writer lists every vertex of the complex) and orients it
  outward.

Not reproducible: the mesher draws its initial points from CGAL's default random generator, which the Python
bindings give no way to seed, so two runs of one cell give different meshes (the bunny at N = 64: 2,500–2,680
vertices, Hausdorff 0.88–1.0 h over 25 runs); the grid's seed does not reach it.

A component that no ray from the centre reaches gets no initial point and is missing from the mesh — a
limitation of the mesher's initialisation, not of the adapter (``info["components"]`` shows it).

The package is an optional dependency: ``pip install cgal`` (or the ``peers`` extra); without it the method
is listed as unavailable and ``reconstruct`` fails in one line.
"""

from __future__ import annotations

import os
import tempfile
import time

import numpy as np
import trimesh

from phantoms import InputError, Volume

from geometry.mesh import mesh_facts

from .base import Method, check_volume
from .contract import Reconstruction, ReconstructionFailed
from .params import Param
from .cost_model import PowerLaw
from .isosurface import orient_outward

__all__ = ["CGALMesher", "write_inr", "read_off_surface", "INSTALL"]

INSTALL = 'pip install cgal (or pip install -e ".[peers]")'

#: the relative precision of the intersection oracle (of the bounding sphere's radius)
ORACLE_PRECISION = 1e-6


def read_off_surface(path: str, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The vertices (float64) and faces (int64) of CGAL's OFF output, without the vertices no facet uses: the
    OFF writer lists every vertex of the complex, and now and then one of them is on no surface facet (a
    closed surface then read Euler characteristic 3).

    Parameters
    ----------
    path : str
        The OFF file.
    name : str
        The method's name, for the error message.

    Raises
    ------
    InputError
        No face, or a non-finite coordinate.
    """
    mesh = trimesh.load(path, file_type="off", process=False, force="mesh")
    if len(mesh.faces) == 0 or not np.isfinite(mesh.vertices).all():
        raise InputError(f"method {name!r}: CGAL's OFF output holds no usable mesh")
    mesh.remove_unreferenced_vertices()
    return np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)


def write_inr(path: str, values: np.ndarray, spacing) -> None:
    """``values`` (nx, ny, nz), axis 0 = x, as a float32 little-endian INRIMAGE-4 file with voxel size
    ``spacing``: a 256-byte header, then the voxels with x fastest."""
    nx, ny, nz = values.shape
    vx, vy, vz = (float(s) for s in spacing)
    header = (f"#INRIMAGE-4#{{\nXDIM={nx}\nYDIM={ny}\nZDIM={nz}\nVDIM=1\nTYPE=float\nPIXSIZE=32 bits\n"
              f"CPU=decm\nVX={vx!r}\nVY={vy!r}\nVZ={vz!r}\n")
    header += "\n" * (252 - len(header)) + "##}\n"
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(np.asarray(values, dtype="<f4").ravel(order="F").tobytes())


class CGALMesher(Method):
    name = "cgal_mesher"
    imports = ("CGAL.CGAL_Surface_mesher", "CGAL.CGAL_Kernel")
    description = ("CGAL's surface mesher (Boissonnat–Oudot Delaunay refinement, cgal bindings): angle, size "
                   "and distance bounds in h")
    params = {
        "angle": Param(30.0, "lower bound on the facets' angles, degrees (CGAL's usual 30; > 30 may not "
                             "terminate)", type=float, min=1.0, max=30.0),
        "size": Param(1.0, "upper bound on the radius of the facets' surface Delaunay balls, in h",
                      type=float, min=0.1, max=100.0),
        "distance": Param(0.1, "upper bound on the distance between a facet's circumcentre and its surface "
                               "Delaunay ball's centre (the approximation bound), in h",
                          type=float, min=0.005, max=100.0),
    }
    requires = {"CGAL": INSTALL}

    #: the cost model: CPU seconds with the default bounds,
    #: the clean sphere and bunny at N = 32–96 together (the bunny is the dearer)
    COST = PowerLaw(a=0.14, p=2.0)

    def estimate_seconds(self, shape, n_crossing_cells: int | None = None) -> float | None:
        """The fit of the defaults, scaled by the facet count, ∝ 1 / size² (a tighter ``distance`` adds facets
        where the surface curves, which is not modelled)."""
        return self.COST.seconds(shape, n_crossing_cells) / self.config["size"] ** 2

    def reconstruct(self, volume: Volume) -> Reconstruction:
        self.require()
        from CGAL import CGAL_Surface_mesher as SM
        from CGAL.CGAL_Kernel import Point_3, Sphere_3

        check_volume(volume, self.name)
        cfg, h = self.config, volume.h
        values = np.asarray(volume.values, dtype=np.float64)
        iso = float(np.abs(values).max()) + 1.0
        spacing = np.asarray(volume.spacing, dtype=np.float64)
        centre = np.array(np.unravel_index(np.argmin(values), values.shape)) * spacing
        corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)]) \
            * (np.asarray(values.shape) - 1) * spacing
        radius = float(np.linalg.norm(corners - centre, axis=1).max()) * 1.01
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory(prefix="cgal_mesher_") as tmp:
            image_path, off_path = os.path.join(tmp, "volume.inr"), os.path.join(tmp, "mesh.off")
            write_inr(image_path, iso - values, spacing)
            image = SM.Gray_level_image_3(image_path, iso)
            surface = SM.Implicit_surface_Gray_level_image_3(image, Sphere_3(Point_3(*map(float, centre)),
                                                                             radius * radius), ORACLE_PRECISION)
            triangulation = SM.Surface_mesh_default_triangulation_3()
            complex_2 = SM.Complex_2_in_triangulation_3(triangulation)
            criteria = SM.Surface_mesh_default_criteria_3(cfg["angle"], cfg["size"] * h, cfg["distance"] * h)
            SM.make_surface_mesh(complex_2, surface, criteria, SM.MANIFOLD_TAG)
            wall = time.perf_counter() - t0
            if complex_2.number_of_facets() == 0:
                raise ReconstructionFailed(f"method {self.name!r}: CGAL's mesher found no surface")
            SM.output_surface_facets_to_off(off_path, complex_2)
            vertices, faces = read_off_surface(off_path, self.name)
        mesh = trimesh.Trimesh(vertices + volume.origin, faces, process=False)
        orient_outward(mesh)
        info = {"iterations": 0, "stop_reason": "done", "wall_cgal_s": wall, "size_world": cfg["size"] * h,
                "distance_world": cfg["distance"] * h}
        info.update({f"mesh_{k}": v for k, v in mesh_facts(mesh).items()})
        return Reconstruction(mesh, info)
