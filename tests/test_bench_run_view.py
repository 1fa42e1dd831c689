"""Tests of ``bench.run.view``: :func:`decimate` bounds the viewer mesh's faces, :func:`view_arrays` carries each
per-vertex colour from the full mesh's nearest vertex."""

from __future__ import annotations

import numpy as np
import trimesh

from bench.run.view import VIEW_FACES, decimate, view_arrays


def test_decimate_bounds_the_faces_and_keeps_a_small_mesh_as_it_is():
    m = trimesh.creation.icosphere(subdivisions=4)                  # 5,120 faces
    v, f = decimate(np.asarray(m.vertices), np.asarray(m.faces), 500)
    assert 0 < len(f) <= 500 and f.max() < len(v)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=0.05)
    small = trimesh.creation.icosphere(subdivisions=1)
    v2, f2 = decimate(small.vertices, small.faces)
    assert v2 is small.vertices and f2 is small.faces


def test_view_arrays_carry_the_colours_of_the_nearest_full_vertex():
    m = trimesh.creation.icosphere(subdivisions=4)
    v = np.asarray(m.vertices)
    out = view_arrays(v, m.faces, {"H": v[:, 2], "d": None, "short": np.ones(3)})
    assert set(out) == {"view_vertices", "view_faces", "view_H"}          # None and wrong lengths left out
    assert out["view_vertices"].dtype == np.float32 and out["view_faces"].dtype == np.int32
    assert len(out["view_faces"]) <= VIEW_FACES
    assert len(out["view_H"]) == len(out["view_vertices"])
    np.testing.assert_allclose(out["view_H"], out["view_vertices"][:, 2], atol=0.1)   # z of a nearby vertex
