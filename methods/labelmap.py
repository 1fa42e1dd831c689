"""What the mask-native methods share: the label map a volume holds and its hand-over to VTK.

A volume of kind ``mask`` or ``intensity`` carries its image (``raw``, inside where raw > ``level``); a signed
distance is read as the mask φ < 0 (:attr:`phantoms.Volume.inside_raw`).  :func:`padded_labels` pads that mask
with one outside voxel on every face (3D Slicer does so when the mask touches the border; a padded face changes
nothing elsewhere), :func:`vtk_image` hands a C-ordered array to VTK without a copy (VTK orders points x fastest,
so the array's axes are reversed: :func:`from_vtk` swaps the output points back, which mirrors the mesh, and
reverses the faces once).
"""

from __future__ import annotations

import numpy as np
import trimesh

from phantoms import InputError, Volume

from .flying_edges import VTK_MISSING
from .marching_cubes import orient_outward

__all__ = ["padded_labels", "vtk_image", "from_vtk", "vtk_modules", "closed_mesh"]


def vtk_modules(name: str):
    """``vtkmodules`` (imported), or one InputError line naming the package."""
    try:
        import vtkmodules.all  # noqa: F401
        import vtkmodules
    except ImportError:
        raise InputError(VTK_MISSING.format(name=name)) from None
    return vtkmodules


def padded_labels(volume: Volume, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(uint8 label map, 1 inside, padded by one outside voxel; world origin of its voxel (0, 0, 0))."""
    inside = volume.inside_raw
    if not inside.any() or inside.all():
        raise InputError(f"method {name!r}: the mask has no {'inside' if not inside.any() else 'outside'} voxels")
    labels = np.pad(inside.astype(np.uint8), 1)
    return labels, volume.origin - volume.spacing


def vtk_image(array: np.ndarray, origin=(0.0, 0.0, 0.0), spacing=(1.0, 1.0, 1.0)):
    """A vtkImageData viewing ``array`` (C-ordered, axis 0 = x) as dimensions (nz, ny, nx); the array must stay
    alive while VTK uses the image."""
    from vtkmodules.util import numpy_support
    from vtkmodules.vtkCommonDataModel import vtkImageData

    a = np.ascontiguousarray(array)
    image = vtkImageData()
    image.SetDimensions(*a.shape[::-1])
    image.SetSpacing(*(float(s) for s in np.broadcast_to(spacing, (3,))[::-1]))
    image.SetOrigin(*(float(o) for o in np.broadcast_to(origin, (3,))[::-1]))
    scalars = numpy_support.numpy_to_vtk(a.reshape(-1), deep=False)
    scalars.SetName("labels")
    image.GetPointData().SetScalars(scalars)
    image._keep = a                          # the buffer VTK reads
    return image


def from_vtk(polydata) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) in our axis order, triangles (F, 3)) of a VTK polydata of triangles."""
    from vtkmodules.util import numpy_support

    if polydata.GetNumberOfPoints() == 0 or polydata.GetNumberOfPolys() == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    pts = numpy_support.vtk_to_numpy(polydata.GetPoints().GetData())
    polys = polydata.GetPolys()
    offsets = numpy_support.vtk_to_numpy(polys.GetOffsetsArray())
    if np.any(np.diff(offsets) != 3):
        raise InputError("VTK returned polygons that are not triangles")
    conn = numpy_support.vtk_to_numpy(polys.GetConnectivityArray())
    return (np.ascontiguousarray(pts[:, ::-1], dtype=np.float64),
            conn.reshape(-1, 3)[:, ::-1].astype(np.int64))


def closed_mesh(vertices: np.ndarray, faces: np.ndarray, name: str) -> trimesh.Trimesh:
    """The triangles as a mesh with exact duplicates merged, degenerate faces dropped, faces outward."""
    if len(faces) == 0:
        raise InputError(f"method {name!r}: no surface was extracted")
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.merge_vertices(digits_vertex=12)
    f = mesh.faces
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])
    if not keep.all():
        mesh.update_faces(keep)
    mesh.remove_unreferenced_vertices()
    return orient_outward(mesh)
