"""phantoms/user_truth.py: a truth from the same data is never refused however thin the shape — the frame check
reads the truth's own signed distance against φ where the first-order estimate |φ| / |∇φ| fails at a ridge — while
a truth shifted by a few voxels still is (the voxel-index and LPS cases: tests/test_phantoms_user.py)."""

from __future__ import annotations

import gpytoolbox as gpy
import numpy as np
import pytest
import trimesh

from geometry.closest import point_mesh_distance
from methods.isosurface import marching_cubes_mesh
from phantoms import InputError, Volume, get_phantom
from phantoms.field import field_normalize
from phantoms.mesh.resolve import solid_boundary
from phantoms.frames import TRUTH_TOLERANCE_VOXELS
from phantoms.frames import distance_in_voxels as _distance_in_voxels

N = 30                       # Reach for the Arcs' grid: (N + 1)³ points over [−1, 1]³
H = 2.0 / N


def _thin_shape(kind: str) -> tuple[np.ndarray, np.ndarray]:
    """A small ball with a part thinner than a voxel (a plate 0.2 h thick, or a limb 0.4 h across) whose middle
    lies half-way between two grid planes — no grid point is inside it — normalised as the field's protocol
    does (unit longest side, centred), so its `field:` grid is the same grid."""
    body = trimesh.creation.icosphere(2, radius=0.15).apply_translation([-0.6, 0, 0])
    if kind == "plate":
        part = trimesh.creation.box(extents=(1.0, 0.8, 0.2 * H)).apply_translation([0, 0, 0.5 * H])
    else:
        part = trimesh.creation.cylinder(radius=0.2 * H, height=1.2, sections=24).apply_transform(
            trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0])).apply_translation([0, 0.5 * H, 0.5 * H])
    part = part.subdivide().subdivide().subdivide()
    v, f = solid_boundary(np.vstack([body.vertices, part.vertices]),
                          np.vstack([body.faces, part.faces + len(body.vertices)]))
    return field_normalize(v), f


def _write(tmp_path, kind):
    """The shape's OBJ and its exact signed distance grid (.npz), as Reach for the Arcs' script builds it."""
    v, f = _thin_shape(kind)
    g = np.linspace(-1, 1, N + 1)
    pts = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    phi = gpy.signed_distance(pts, v, f.astype(np.int32))[0].reshape(N + 1, N + 1, N + 1)
    obj, npz = tmp_path / f"{kind}.obj", tmp_path / f"{kind}.npz"
    trimesh.Trimesh(v, f, process=False).export(str(obj))
    np.savez(npz, values=phi, origin=np.full(3, -1.0), spacing=np.full(3, H))
    return obj, npz, v, f


def _chamfer(mesh, truth_v, truth_f, truth_phantom) -> float:
    """Mean distance both ways: the mesh's vertices to the truth, the truth's vertices to the mesh."""
    there = np.abs(truth_phantom.sdf(mesh.vertices)).mean()
    back = point_mesh_distance(truth_v, np.asarray(mesh.vertices), np.asarray(mesh.faces)).mean()
    return float(there + back)


@pytest.mark.parametrize("kind", ["plate", "limb"])
def test_a_thin_shapes_truth_from_the_same_grid_is_accepted(tmp_path, kind):
    obj, npz, v, f = _write(tmp_path, kind)
    vol = Volume(np.load(npz)["values"], origin=[-1.0] * 3, spacing=H)
    assert _distance_in_voxels(v, vol) > TRUTH_TOLERANCE_VOXELS      # the first-order estimate alone refuses it
    ph = get_phantom(f"volume:{npz}?truth={obj}&mask=no")
    assert ph.has_truth and ph.volume().shape == (N + 1,) * 3
    field = get_phantom(f"field:mesh:{obj}")
    fvol = field.volume(n=N + 1, extent=1.0)
    assert np.allclose(fvol.values, ph.volume().values, atol=1e-6)          # the OBJ keeps 8 decimals
    a = _chamfer(marching_cubes_mesh(ph.volume()), v, f, ph.ground_truth())
    b = _chamfer(marching_cubes_mesh(fvol), field.vertices, field.faces, field)
    assert a == pytest.approx(b, rel=0.01) and a > 0.1 * H      # the thin part is missed by both alike


@pytest.mark.parametrize("kind", ["plate", "limb"])
def test_a_thin_shapes_truth_shifted_by_three_voxels_is_refused(tmp_path, kind):
    obj, npz, v, f = _write(tmp_path, kind)
    trimesh.Trimesh(v + [0, 0, 3 * H], f, process=False).export(str(tmp_path / "shifted.obj"))
    with pytest.raises(InputError, match="voxels or more from the zero level set"):
        get_phantom(f"volume:{npz}?truth={tmp_path / 'shifted.obj'}&mask=no")


def test_a_level_set_of_another_scale_is_not_read_as_a_distance(tmp_path):
    """φ / 100 has the same zero set but is no distance: the distance comparison declines it, and the thin shape's
    truth is judged by the first-order estimate alone — refused, not accepted by a comparison that cannot hold."""
    obj, npz, v, f = _write(tmp_path, "plate")
    z = np.load(npz)
    np.savez(tmp_path / "scaled.npz", values=z["values"] / 100.0, origin=z["origin"], spacing=z["spacing"])
    with pytest.raises(InputError, match="voxels or more from the zero level set"):
        get_phantom(f"volume:{tmp_path / 'scaled.npz'}?truth={obj}&mask=no")
