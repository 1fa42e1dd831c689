"""methods/labelmap.py: the mask a volume holds and its hand-over to VTK (axis order, world placement)."""

import numpy as np
import pytest

from methods.isosurface import closed_mesh, from_vtk, vtk_image
from methods.labelmap import padded_labels
from phantoms import InputError, Volume, mask_to_sdf


def _box_volume(spacing=(0.5, 0.7, 1.3), origin=(1.0, -2.0, 3.0)):
    m = np.zeros((12, 9, 7), bool)
    m[2:9, 3:6, 2:5] = True                    # 7 x 3 x 3 voxels: every axis different
    sdf = mask_to_sdf(m, origin, spacing)
    return Volume(sdf.values, sdf.origin, sdf.spacing, kind="mask", raw=m.astype(float), level=0.5), m


def test_the_discrete_surface_of_a_box_lands_half_a_voxel_outside_its_voxel_centres_in_world_units():
    from vtkmodules.vtkFiltersGeneral import vtkDiscreteFlyingEdges3D

    vol, m = _box_volume()
    labels, origin = padded_labels(vol, "t")
    assert labels.shape == tuple(s + 2 for s in m.shape) and labels[1:-1, 1:-1, 1:-1].sum() == m.sum()
    fe = vtkDiscreteFlyingEdges3D()
    fe.SetInputData(vtk_image(labels))
    fe.SetValue(0, 1)
    fe.Update()
    ijk, faces = from_vtk(fe.GetOutput())
    mesh = closed_mesh(origin + ijk * vol.spacing, faces, "t")
    idx = np.argwhere(m)
    lo = vol.origin + (idx.min(0) - 0.5) * vol.spacing
    hi = vol.origin + (idx.max(0) + 0.5) * vol.spacing
    assert np.allclose(mesh.bounds, [lo, hi]) and mesh.is_watertight and mesh.volume > 0
    assert mesh.volume == pytest.approx(m.sum() * np.prod(vol.spacing) * 0.9, rel=0.1)   # corners cut


def test_a_signed_distance_is_read_as_its_negative_part_and_an_empty_mask_is_refused():
    vol, m = _box_volume()
    plain = Volume(vol.values, vol.origin, vol.spacing)
    assert np.array_equal(padded_labels(plain, "t")[0][1:-1, 1:-1, 1:-1].astype(bool), m)
    with pytest.raises(InputError, match="no inside voxels"):
        padded_labels(Volume(np.abs(vol.values) + 1, vol.origin, vol.spacing), "t")
