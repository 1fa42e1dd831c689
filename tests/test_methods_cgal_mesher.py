"""methods/cgal_mesher.py: CGAL's surface mesher through the ``cgal`` bindings — closed, outward, on φ = 0 (the
suite's validity check) and close to the truth on the sphere and the bunny at N = 64; world coordinates on an
anisotropic, off-centre grid (CGAL's image frame starts at 0); the INRIMAGE writer; the size bound; without
the package, listed as unavailable with the install command."""

from __future__ import annotations

import numpy as np
import pytest

from methods import get_method
from methods.cgal_mesher import read_off_surface, write_inr

from _optional_peers import check_bad_input, check_missing_package, validity
from _peers_common import (RADIUS, check_closed_outward, edge_and_vertex_manifold, hausdorff_h, offcentre_sphere,
                           sphere_errors, volume)

N = 64


@pytest.mark.parametrize("phantom, bound", [("sphere", 0.1), ("bunny", 1.2)])    # measured 0.056 h, 0.92 h
def test_valid_and_close_at_64(phantom, bound):
    pytest.importorskip("CGAL")
    vol = volume(phantom, N)
    rec = get_method("cgal_mesher").reconstruct(vol)
    assert validity(rec.mesh, vol) == []
    check_closed_outward(rec.mesh, f"cgal_mesher on {phantom}")
    assert edge_and_vertex_manifold(rec.mesh)
    assert hausdorff_h(rec.mesh, phantom, vol.h) <= bound
    if phantom == "sphere":      # the vertices lie on the trilinear zero set: radial error ≪ h (measured 0.02 h)
        assert np.abs(np.linalg.norm(rec.mesh.vertices, axis=1) - 1.0).max() < 0.05 * vol.h


def test_world_coordinates_anisotropic_offcentre():
    pytest.importorskip("CGAL")
    vol = offcentre_sphere()
    rec = get_method("cgal_mesher").reconstruct(vol)
    check_closed_outward(rec.mesh, "cgal_mesher on the off-centre sphere")
    err, centre_offset = sphere_errors(rec.mesh)
    assert err < 0.1 * vol.spacing.min()                            # measured 0.036 of the smallest spacing
    assert np.abs(centre_offset).max() < 0.05 * vol.spacing.min()   # a Delaunay sample: not symmetric
    assert rec.mesh.volume == pytest.approx(4 / 3 * np.pi * RADIUS**3, rel=0.02)


def test_size_bound_sets_the_sampling():
    pytest.importorskip("CGAL")
    vol = volume("sphere", 48)
    fine = get_method("cgal_mesher", size=0.5).reconstruct(vol).mesh
    coarse = get_method("cgal_mesher", size=2.0).reconstruct(vol).mesh
    assert len(fine.faces) > 4 * len(coarse.faces)
    edges = coarse.edges_unique_length
    assert edges.max() <= 2 * 2.0 * vol.h * 1.01                    # an edge is a chord of a ball of radius ≤ size


def test_inr_header_and_voxel_order(tmp_path):
    values = np.arange(2 * 3 * 4, dtype=float).reshape(2, 3, 4)
    path = tmp_path / "v.inr"
    write_inr(str(path), values, (0.5, 0.25, 2.0))
    raw = path.read_bytes()
    header = raw[:256].decode("ascii")
    assert header.startswith("#INRIMAGE-4#{\n") and header.endswith("##}\n")
    assert "XDIM=2\nYDIM=3\nZDIM=4\n" in header and "VX=0.5\nVY=0.25\nVZ=2.0\n" in header
    data = np.frombuffer(raw[256:], dtype="<f4")
    assert len(data) == values.size and data[1] == values[1, 0, 0] and data[2] == values[0, 1, 0]


def test_without_the_package_listed_unavailable(monkeypatch, tmp_path, capsys):
    check_missing_package(monkeypatch, tmp_path, capsys, "cgal_mesher", "CGAL", "pip install cgal")


def test_bad_input_is_one_line_naming_the_method():
    pytest.importorskip("CGAL")
    check_bad_input("cgal_mesher", size=0.0, angle=45.0)


def test_the_off_reader_drops_a_vertex_no_facet_uses(tmp_path):
    """CGAL's OFF writer lists every vertex of the complex; one on no facet made a closed surface read χ = 3."""
    import trimesh

    tet = trimesh.creation.box().convex_hull
    v, f = np.asarray(tet.vertices), np.asarray(tet.faces)
    stray = np.vstack([v[:3], [[9.0, 9.0, 9.0]], v[3:]])             # the stray vertex is the fourth
    faces = np.where(f >= 3, f + 1, f)
    lines = ["OFF", f"{len(stray)} {len(faces)} 0"] + [" ".join(map(str, p)) for p in stray] + \
        [f"3 {a} {b} {c}" for a, b, c in faces]
    (tmp_path / "m.off").write_text("\n".join(lines) + "\n")
    got_v, got_f = read_off_surface(str(tmp_path / "m.off"), "cgal_mesher")
    assert len(got_v) == len(v) and not np.any(np.all(got_v == 9.0, axis=1))
    np.testing.assert_allclose(got_v[got_f], v[f])                   # the same triangles, renumbered
    mesh = trimesh.Trimesh(got_v, got_f, process=False)
    assert mesh.euler_number == 2 and mesh.is_watertight

