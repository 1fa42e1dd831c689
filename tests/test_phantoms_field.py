"""The field's protocol (phantoms/field.py): the papers' normalisation and grid, rebuilt here as their scripts do."""

from __future__ import annotations

import numpy as np
import pytest

from geometry.errors import InputError
from phantoms import get_phantom, is_phantom_name
from phantoms.field import field_normalize, parse_field_spec
from phantoms.real import bunny_path
from phantoms.registry import check_phantom_files


def _papers_bunny():
    """The bunny as the papers' scripts read it (gpytoolbox's reader; its C++ one needs a C locale)."""
    import gpytoolbox as gpy

    v, f = gpy.read_mesh(str(bunny_path()), reader="Python")
    return v, f.astype(np.int32)


def _rfta_grid(n):
    """Reach for the Arcs, ``get_sdf_data``: (n + 1)³ points over [−1, 1]³, numpy's default 'xy' meshgrid."""
    gx, gy, gz = np.meshgrid(np.linspace(-1.0, 1.0, n + 1), np.linspace(-1.0, 1.0, n + 1),
                             np.linspace(-1.0, 1.0, n + 1))
    return np.vstack((gx.flatten(), gy.flatten(), gz.flatten())).T


def _carrera_grid(res):
    """Carrera et al., ``contouring.build_grid((res,) * 3)``: libigl's ``igl::grid`` (x fastest, i / (res − 1))
    times the extent 2 plus the corner −1."""
    t = np.arange(res) / float(res - 1)
    z, y, x = np.meshgrid(t, t, t, indexing="ij")
    return np.column_stack([x.ravel(), y.ravel(), z.ravel()]) * 2.0 + -1.0


def _on_suite_grid(vol, U):
    """Each of the papers' points as an index of the suite's grid, and the largest distance between the two."""
    ijk = np.rint((U - vol.origin) / vol.h).astype(int)
    assert ijk.min() == 0 and ijk.max() == vol.shape[0] - 1
    assert len(np.unique(ijk, axis=0)) == len(U) == vol.values.size
    return ijk, float(np.abs(vol.index_to_world(ijk) - U).max())


def test_normalisation_is_gpytoolboxs_normalize_points():
    import gpytoolbox as gpy

    v, _ = _papers_bunny()
    ref = gpy.normalize_points(v.copy())
    np.testing.assert_allclose(field_normalize(v), ref, rtol=0, atol=1e-15)
    np.testing.assert_allclose(field_normalize(v, 1.5), ref * 1.5, rtol=0, atol=1e-15)
    ph = get_phantom("field:bunny")
    span = ph.vertices.max(0) - ph.vertices.min(0)
    assert span.max() == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(ph.vertices.max(0) + ph.vertices.min(0), 0.0, atol=1e-15)
    # the phantom undoes the suite's own normalisation first: the same vertices to rounding
    np.testing.assert_allclose(np.sort(ph.vertices, axis=0), np.sort(ref, axis=0), rtol=0, atol=1e-13)


def test_reach_for_the_arcs_grid_points_values_and_marching_cubes():
    """n = 32: the suite's N = 33 grid over [−1, 1]³ holds the script's 33³ points and its values
    (gpy.signed_distance of the normalised bunny), and the suite's marching cubes gives the mesh of the script's
    own call, gpy.marching_cubes(S, U, n + 1, n + 1, n + 1): the same vertices (to float32-level rounding of
    libigl's interpolation, 1e-6 h)."""
    import gpytoolbox as gpy
    from scipy.spatial import cKDTree

    from methods import get_method

    v, f = _papers_bunny()
    V_gt = gpy.normalize_points(v.copy())
    n = 32
    U = _rfta_grid(n)
    S = gpy.signed_distance(U, V_gt, f)[0]
    vol = get_phantom("field:bunny").volume(n=n + 1, extent=1.0)
    ijk, gap = _on_suite_grid(vol, U)
    assert gap == 0.0
    assert np.abs(vol.values[tuple(ijk.T)] - S).max() < 1e-12
    Vp, _ = gpy.marching_cubes(S, U, n + 1, n + 1, n + 1)
    mesh = get_method("marching_cubes").reconstruct(vol).mesh
    assert len(mesh.vertices) == len(Vp) > 500
    assert cKDTree(Vp).query(np.asarray(mesh.vertices))[0].max() < 1e-6 * vol.h
    assert cKDTree(np.asarray(mesh.vertices)).query(Vp)[0].max() < 1e-6 * vol.h


def test_carrera_grid_points_and_values():
    """res = 32 with the shape × 1.5: the suite's N = 32 grid is build_grid's points (to one rounding) and
    values."""
    import gpytoolbox as gpy

    v, f = _papers_bunny()
    V_gt = gpy.normalize_points(v.copy()) * 1.5
    U = _carrera_grid(32)
    S = gpy.signed_distance(U, V_gt, f)[0]
    vol = get_phantom("field:bunny?scale=1.5").volume(n=32, extent=1.0)
    ijk, gap = _on_suite_grid(vol, U)
    assert gap < 1e-15
    assert np.abs(vol.values[tuple(ijk.T)] - S).max() < 1e-12


def test_values_equal_the_suites_certified_distance_near_the_surface():
    """Independently of gpytoolbox: the suite's certified closest-point query (MeshPhantom.sdf) at every grid
    point within 3h of the surface, and its own grid (exact there, an upper bound beyond) never below it."""
    ph = get_phantom("field:bunny")
    vol = ph.volume(n=33, extent=1.0)
    flat = vol.values.reshape(-1)
    band = np.flatnonzero(np.abs(flat) < 3 * vol.h)
    pts = vol.index_to_world(np.stack(np.unravel_index(band, vol.shape), 1))
    assert len(band) > 1000
    np.testing.assert_allclose(flat[band], ph.sdf(pts), rtol=0, atol=1e-12)
    own = ph.signed_distance_grid(33, 1.0).reshape(-1)
    assert (np.abs(own) >= np.abs(flat) - 1e-12).all()


def test_specs_and_refusals():
    assert parse_field_spec("field:bunny") == ("bunny", 1.0)
    assert parse_field_spec("field:mesh:a/b.obj?scale=1.5") == ("mesh:a/b.obj", 1.5)
    assert is_phantom_name("field:bunny") and is_phantom_name("field:mesh:x.obj")
    assert not is_phantom_name("field:nope") and not is_phantom_name("field:field:bunny")
    for spec, msg in [("field:sphere", "takes a mesh phantom"), ("field:bunny?scale=-1", "positive"),
                      ("field:bunny?size=2", "unknown option"), ("field:", "name a mesh phantom"),
                      ("field:bunny?scale=x", "must be a number")]:
        with pytest.raises(InputError, match=msg) as err:
            get_phantom(spec)
        assert "\n" not in str(err.value)
    with pytest.raises(InputError, match="no such mesh file"):
        check_phantom_files("field:mesh:/nonexistent/shape.obj")
    for spec, msg in [("field:sphere", "takes a mesh phantom"), ("field:bunny?scale=1.5&scale=2", "given twice")]:
        with pytest.raises(InputError, match=msg):          # before any work: no file read, no volume built
            check_phantom_files(spec)
    assert is_phantom_name("field:bunny?scale=1.5&scale=2")     # a phantom's name; its options fail on their own
