"""What the surface-extraction adapters share: marching cubes at level 0, the mesh clean-up every extracted
surface gets, and the hand-over of an image to VTK and of VTK's triangles back.

* :func:`marching_cubes_mesh` — scikit-image's marching cubes of a volume: the zero level set of the trilinear
  interpolant, triangulated cell by cell, in world coordinates (``origin + index * spacing``), cleaned by
  :func:`clean_mesh`.  The marching-cubes baseline and the start of DistMesh, screened Poisson, Reach for the
  Spheres and the Taubin-smoothed variant.
* :func:`nudge_zeros` — exact zeros moved a hair outside, so no vertex sits on a grid point several cell edges
  share (marching cubes, Flying Edges, dual contouring, OpenVDB).
* :func:`clean_mesh` (exact duplicates merged, degenerate and duplicate faces dropped), :func:`closed_mesh` (the
  same for VTK's outputs, which share their vertices already) and :func:`orient_outward` (faces flipped when the
  enclosed volume is negative: φ < 0 inside, so the normals point up the gradient).
* The VTK bridge: :func:`vtk_image` hands a C-ordered array to VTK without a copy.  VTK orders points x fastest
  and a C-ordered ``values[i, j, k]`` (axis 0 = x) has z fastest, so the array is handed over as it is as an
  image of dimensions (nz, ny, nx), spacing and origin reversed; :func:`from_vtk` swaps the output points'
  columns back (z, y, x → x, y, z), which mirrors the mesh, so it reverses the faces once.
  :func:`require_vtk` imports a VTK module or raises one line naming the package.
"""

from __future__ import annotations

import importlib

import numpy as np
import trimesh

from geometry.mesh import signed_volume
from phantoms import InputError, Volume

__all__ = ["VTK_MISSING", "nudge_zeros", "marching_cubes_mesh", "clean_mesh", "closed_mesh", "orient_outward",
           "require_vtk", "vtk_image", "from_vtk"]

VTK_MISSING = 'method {name!r} needs VTK, which is not installed: pip install "vtk>=9.3"'


def nudge_zeros(values: np.ndarray) -> np.ndarray:
    """Move exact zeros a hair to the outside (φ > 0); ``values`` itself when it holds none.

    A grid value of exactly 0 puts marching-cubes vertices of several edges on the same grid point, which
    after merging leaves pinched, non-manifold vertices; a positive value 1e-9 of the value range away keeps
    the vertices distinct (≈ 1e-9 of the grid size apart) and the mesh manifold.
    """
    zero = values == 0.0
    if not zero.any():
        return values
    scale = float(np.abs(values).max()) or 1.0
    out = values.copy()
    out[zero] = 1e-9 * scale
    return out


def clean_mesh(vertices: np.ndarray, faces: np.ndarray) -> trimesh.Trimesh:
    """A trimesh with exact-duplicate vertices merged, degenerate/duplicate faces and unused vertices dropped,
    and faces oriented outward (positive signed volume) when the mesh is watertight."""
    mesh = trimesh.Trimesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64),
                           process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True, digits_vertex=12)
    f = mesh.faces
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    if not keep.all():
        mesh.update_faces(keep)
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    orient_outward(mesh)
    return mesh


def closed_mesh(vertices: np.ndarray, faces: np.ndarray, name: str, merge: bool = True) -> trimesh.Trimesh:
    """The triangles as a mesh with faces repeating a vertex dropped, faces outward; ``merge``: exact duplicate
    vertices merged first.  VTK's filters share their vertices already (``merge`` False): smoothing can move
    two distinct vertices onto one point, and merging them would pinch the surface into non-manifold edges."""
    if len(faces) == 0:
        raise InputError(f"method {name!r}: no surface was extracted")
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    if merge:
        mesh.merge_vertices(digits_vertex=12)
    f = mesh.faces
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    if not keep.all():
        mesh.update_faces(keep)
    mesh.remove_unreferenced_vertices()
    return orient_outward(mesh)


def orient_outward(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Flip all faces when the enclosed (signed) volume is negative. In place; returns the mesh."""
    if len(mesh.faces) and signed_volume(mesh.vertices, mesh.faces) < 0:
        mesh.faces = mesh.faces[:, ::-1].copy()
    return mesh


def marching_cubes_mesh(volume: Volume, *, method: str = "lewiner", step_size: int = 1,
                        name: str = "marching_cubes") -> trimesh.Trimesh:
    """Marching cubes of ``volume`` at level 0: a clean, outward-oriented mesh in world coordinates."""
    from skimage.measure import marching_cubes

    values = nudge_zeros(volume.values)
    if not (values.min() < 0.0 < values.max()):
        raise InputError(f"method {name!r}: the volume has no zero crossing")
    try:
        verts, faces, _, _ = marching_cubes(values, level=0.0, spacing=tuple(float(s) for s in volume.spacing),
                                            step_size=int(step_size), method=method, allow_degenerate=False)
    except (ValueError, RuntimeError) as exc:
        raise InputError(f"method {name!r}: marching cubes failed ({exc}); parameter 'step_size'="
                         f"{step_size} may be too coarse for this volume") from None
    verts = verts + volume.origin
    return clean_mesh(verts, faces)


def require_vtk(name: str, module: str = "vtkmodules.all"):
    """The VTK module ``module`` (imported), or one InputError line saying method ``name`` needs VTK."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise InputError(VTK_MISSING.format(name=name)) from None


def vtk_image(array: np.ndarray, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0), scalars: str = "labels"):
    """A vtkImageData viewing ``array`` (C-ordered, axis 0 = x) as dimensions (nz, ny, nx), with ``origin`` and
    ``spacing`` (ours, per axis or one number) reversed, its point scalars named ``scalars``; no copy of a
    C-contiguous array, which must stay alive while VTK uses the image (the image holds a reference)."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonDataModel import vtkImageData

    a = np.ascontiguousarray(array)
    image = vtkImageData()
    image.SetDimensions(*a.shape[::-1])                  # VTK's x = our z (the fastest axis in memory)
    image.SetSpacing(*(float(s) for s in np.broadcast_to(spacing, (3,))[::-1]))
    image.SetOrigin(*(float(o) for o in np.broadcast_to(origin, (3,))[::-1]))
    values = numpy_support.numpy_to_vtk(a.reshape(-1), deep=False)   # a view: VTK reads numpy's buffer
    values.SetName(scalars)
    image.GetPointData().SetScalars(values)
    image._keep = a                          # the buffer VTK reads
    return image


def from_vtk(polydata) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) in our axis order, triangles (F, 3) re-wound) of a VTK polydata of triangles made from a
    :func:`vtk_image`; empty arrays when it holds none."""
    from vtkmodules.util import numpy_support

    if polydata.GetNumberOfPoints() == 0 or polydata.GetNumberOfPolys() == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    pts = numpy_support.vtk_to_numpy(polydata.GetPoints().GetData())
    polys = polydata.GetPolys()
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray())
    if np.any(np.diff(offsets) != 3):
        raise InputError("VTK returned polygons that are not triangles")
    conn = numpy_support.vtk_to_numpy(polys.GetConnectivityArray())
    return (np.ascontiguousarray(pts[:, ::-1], dtype=np.float64),         # (z, y, x) → (x, y, z)
            conn.reshape(-1, 3)[:, ::-1].astype(np.int64))              # the axis swap is a mirror: re-wind
