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


def test_a_detailed_shape_keeps_more_faces_than_a_sphere_within_the_tolerance():
    """Level of detail: a sphere reads at the starting count, a shape with many thin features needs more."""
    from bench.run.view import MAX_VIEW_FACES, VIEW_TOLERANCE, decimate_to_tolerance
    from geometry.closest import point_mesh_distance

    sphere = trimesh.creation.icosphere(subdivisions=5)                         # 20,480 faces
    v, f = decimate_to_tolerance(sphere.vertices, sphere.faces)
    assert len(f) <= VIEW_FACES
    # 60 thin spikes (0.03 wide, 0.6 long) on the sphere: a 1,000-face mesh cuts them off
    rng = np.random.default_rng(0)
    spikes = []
    for d in rng.normal(size=(60, 3)):
        d /= np.linalg.norm(d)
        c = trimesh.creation.cylinder(radius=0.015, segment=[d * 0.9, d * 1.6], sections=8)
        spikes.append(c)
    spiky = trimesh.util.concatenate([sphere, *spikes])
    v2, f2 = decimate_to_tolerance(spiky.vertices, spiky.faces)
    assert VIEW_FACES < len(f2) <= MAX_VIEW_FACES
    diag = np.linalg.norm(np.ptp(spiky.vertices, axis=0))
    d = point_mesh_distance(np.asarray(spiky.vertices), v2, f2)
    assert np.percentile(d, 95) <= VIEW_TOLERANCE * diag             # the spikes are kept
