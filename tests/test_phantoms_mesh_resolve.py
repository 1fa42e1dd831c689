"""phantoms/mesh/resolve.py: a closed mesh whose parts cross or nest becomes the boundary of its winding-number ≥ ½
solid — checked against closed-form volumes, the exact winding number, and the suite's crossing test."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from geometry.errors import InputError
from geometry.intersections import crossing_pairs
from geometry.mesh import signed_volume
from phantoms.mesh import MeshPhantom, winding_number
from phantoms.mesh.resolve import resolve_if_needed, solid_boundary, winding_layers


def _ball_union(r: float, d: float) -> float:
    """Volume of the union of two balls of radius r whose centres are d < 2r apart (minus the lens)."""
    return 2 * 4 / 3 * np.pi * r ** 3 - np.pi * (4 * r + d) * (2 * r - d) ** 2 / 12


def _inradius(v, f) -> float:
    """Distance from the centre (0) to the nearest face plane of an inscribed icosphere."""
    n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return float(np.abs(np.einsum("ij,ij->i", n / np.linalg.norm(n, axis=1, keepdims=True), v[f[:, 0]])).min())


def test_two_overlapping_spheres_resolve_to_their_union():
    """Unit icospheres 1 apart: the union of the two polyhedra contains the union of the balls of their inradius
    and lies in the union of the unit balls, so its volume is bracketed by two closed forms — both within 0.1 % of
    the unit balls' union at this subdivision.  The result crosses nowhere and the pseudonormal sign of the
    resolved phantom agrees with the exact winding number of the input at points in the overlap."""
    s = trimesh.creation.icosphere(subdivisions=5)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    two_v, two_f = np.vstack([v, v + [1.0, 0, 0]]), np.vstack([f, f + len(v)])
    r_in = _inradius(v, f)
    lo, hi, exact = _ball_union(r_in, 1.0), _ball_union(1.0, 1.0), _ball_union(1.0, 1.0)
    assert (hi - lo) / exact < 1e-3
    ph = MeshPhantom(two_v, two_f, normalize=False)
    res = ph.resolution
    assert res is not None and res.crossing_faces > 0 and res.nested_components == 0
    assert lo <= ph.solid_volume <= hi and abs(ph.solid_volume / exact - 1) < 1e-3
    assert res.faces_in == len(two_f) and res.faces_out == len(ph.faces)
    assert res.volume_change == pytest.approx(ph.solid_volume / signed_volume(two_v, two_f) - 1)
    assert len(crossing_pairs(ph.vertices, ph.faces)) == 0 and ph.n_components == 1
    assert "winding-number ≥ ½ solid" in ph.description and "crossing faces" in ph.description
    assert ph.params["resolved"]["faces_out"] == len(ph.faces)
    # inside one sphere just outside the other's sheet: the unresolved mesh's nearest sheet is the other's
    p = np.array([[-0.2, 0.0, 0.0], [0.5, 0.0, 0.0], [1.2, 0.3, 0.0], [2.5, 0.0, 0.0]])
    w = winding_number(two_v, two_f, p)
    assert np.array_equal(np.sign(ph.sdf(p)) < 0, w >= 0.5)


def test_a_tip_through_one_face_is_cut_off_exactly():
    """A tetrahedron whose apex pierces one face of a box by 0.1 (its base 0.6 above the apex, parallel to the
    face): the union is the box plus the tetrahedron less its tip, a similar tetrahedron scaled by 0.1 / 0.6."""
    box = trimesh.creation.box(extents=(2, 2, 2))
    apex = np.array([0.3, 0.2, 0.9])
    base = np.array([[0.0, -0.3, 1.5], [0.7, 0.1, 1.5], [0.1, 0.6, 1.5]])
    tv = np.vstack([base, apex])
    tf = np.array([[0, 1, 2], [0, 3, 1], [1, 3, 2], [2, 3, 0]])
    if signed_volume(tv, tf) < 0:
        tf = tf[:, ::-1]
    v = np.vstack([box.vertices, tv])
    f = np.vstack([box.faces, tf + len(box.vertices)])
    n_cross = len(np.unique(crossing_pairs(v, f)))
    assert n_cross == 4                                          # one face of the box, three of the tetrahedron
    rv, rf, res = resolve_if_needed(v, f)
    tet = signed_volume(tv, tf)
    expected = 8.0 + tet - tet * (0.1 / 0.6) ** 3
    assert res.crossing_faces == 4
    assert signed_volume(rv, rf) == pytest.approx(expected, rel=1e-12)
    assert len(crossing_pairs(rv, rf)) == 0


def test_nested_shells_same_orientation_keep_the_outer_a_cavity_stays():
    """A sphere inside a sphere, both outward, winds 2 inside the inner one: the w ≥ ½ solid is the outer ball
    and the inner sheet goes.  Wound inward, the inner sphere is a cavity's wall (w = 0 inside it): one solid as
    it is, left alone."""
    s = trimesh.creation.icosphere(subdivisions=3)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    nv, nf = np.vstack([v, 0.5 * v]), np.vstack([f, f + len(v)])
    assert list(winding_layers(nv, nf)) == [0, 1]
    ph = MeshPhantom(nv, nf, normalize=False)
    assert ph.resolution.nested_components == 1 and ph.resolution.crossing_faces == 0
    assert len(ph.faces) == len(f) and ph.solid_volume == pytest.approx(signed_volume(v, f), rel=1e-12)
    assert ph.sdf([[0.7, 0.0, 0.0]])[0] < 0                        # between the shells: inside the solid
    cavity_f = np.vstack([f, f[:, ::-1] + len(v)])
    cav = MeshPhantom(nv, cavity_f, normalize=False)
    assert cav.resolution is None and len(cav.faces) == 2 * len(f)
    assert cav.sdf([[0.7, 0, 0], [0.2, 0, 0]]).tolist()[0] < 0 < cav.sdf([[0.2, 0, 0]])[0]


def test_a_mesh_that_bounds_one_solid_is_left_alone():
    s = trimesh.creation.icosphere(subdivisions=2)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    apart_v, apart_f = np.vstack([v, v + [3.0, 0, 0]]), np.vstack([f, f + len(v)])
    rv, rf, res = resolve_if_needed(apart_v, apart_f)
    assert res is None and rv is not None and np.array_equal(rf, apart_f)


def test_a_failed_resolution_is_refused_naming_why(monkeypatch):
    """Where the boolean fails the mesh is refused as before, with the boolean's reason."""
    import pymeshlab

    def broken(self, **kwargs):
        raise pymeshlab.PyMeshLabException("the inputs are not PWN")

    monkeypatch.setattr(pymeshlab.MeshSet, "generate_boolean_union", broken, raising=False)
    s = trimesh.creation.icosphere(subdivisions=2)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    two_v, two_f = np.vstack([v, v + [1.0, 0, 0]]), np.vstack([f, f + len(v)])
    with pytest.raises(InputError, match="resolving its crossings failed: .*not PWN"):
        MeshPhantom(two_v, two_f)
    with pytest.raises(InputError, match="resolving its crossings failed"):
        solid_boundary(two_v, two_f)
