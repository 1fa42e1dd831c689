"""Topology counts and SIF % (bench/metrics/topology.py): hand-counted known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from bench.metrics import evaluate
from bench.metrics.topology import sif_pct, topology_metrics


def uv_sphere(n_seg: int = 16, n_ring: int = 12, radius: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Outward UV sphere: poles and n_ring − 1 rings at polar angles iπ/n_ring, n_seg vertices per ring;
    pole fans and bands of planar trapezoids, each split into two triangles."""
    th = np.arange(1, n_ring) * math.pi / n_ring
    ph = np.arange(n_seg) * 2 * math.pi / n_seg
    ring = np.stack([np.outer(np.sin(th), np.cos(ph)), np.outer(np.sin(th), np.sin(ph)),
                     np.outer(np.cos(th), np.ones(n_seg))], axis=-1).reshape(-1, 3)
    v = np.vstack([[0, 0, 1], ring, [0, 0, -1]]) * radius
    j = np.arange(n_seg)
    jn = (j + 1) % n_seg
    faces = [np.column_stack([np.zeros(n_seg, int), 1 + j, 1 + jn])]                 # north fan
    for i in range(n_ring - 2):
        a, b = 1 + i * n_seg, 1 + (i + 1) * n_seg
        faces += [np.column_stack([a + j, b + j, b + jn]), np.column_stack([a + j, b + jn, a + jn])]
    s = len(v) - 1
    last = 1 + (n_ring - 2) * n_seg
    faces.append(np.column_stack([np.full(n_seg, s), last + jn, last + j]))          # south fan
    return v, np.concatenate(faces)


def test_uv_sphere_is_closed_and_outward():
    v, f = uv_sphere()
    m = trimesh.Trimesh(v, f, process=False)
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0


def test_sif_of_two_interpenetrating_spheres_is_the_hand_count():
    """Sphere B is sphere A moved by d along the pole axis.  Both are surfaces of revolution over the same
    wedges, with the same profile polyline r(z), so they meet exactly where r(z) = r(z − d): at z = d/2 (the
    profile decreases strictly with |z|).  The faces that meet the other sphere are A's band containing z = d/2
    and B's band containing it — 2·n_seg triangles each — and no others.  With n_seg = 16, n_ring = 12, d = 0.5:
    A's band is between the rings at z = cos 75° = 0.259 and z = 0, B's between 0.241 and 0.5 (both strictly
    contain 0.25), so 64 of the 2 · 352 faces: SIF = 100 · 64 / 704 = 100 / 11 %."""
    n_seg, n_ring, d = 16, 12, 0.5
    v, f = uv_sphere(n_seg, n_ring)
    both_v = np.vstack([v, v + [0.0, 0.0, d]])
    both_f = np.vstack([f, f + len(v)])
    assert len(f) == 2 * n_seg * (n_ring - 1)
    out = evaluate(trimesh.Trimesh(both_v, both_f, process=False), None, 0.1, n_samples=2000)
    assert out["sif_pct"] == pytest.approx(100.0 * 4 * n_seg / (2 * len(f)))
    assert out["sif_pct"] == pytest.approx(100.0 / 11)
    assert out["self_intersections"] > 0 and out["components"] == 2
    # a single sphere: none
    assert evaluate(trimesh.Trimesh(v, f, process=False), None, 0.1, n_samples=2000)["sif_pct"] == 0.0


def test_sif_pct_counts_faces_not_pairs():
    pairs = np.array([[0, 5], [0, 6], [1, 5]])
    assert sif_pct(pairs, 10) == pytest.approx(40.0)     # faces 0, 1, 5, 6 of 10
    assert sif_pct(np.zeros((0, 2), int), 10) == 0.0


def test_boundary_and_nonmanifold_edges_hand_count():
    v, f = uv_sphere(8, 6)
    closed = topology_metrics(v, f)
    assert closed == {"watertight": True, "boundary_edges": 0, "nonmanifold_edges": 0, "euler": 2, "components": 1}
    # remove the 8 faces of the north fan: an open cap whose rim has 8 boundary edges
    opened = topology_metrics(v, f[8:])
    assert opened["boundary_edges"] == 8 and opened["nonmanifold_edges"] == 0 and not opened["watertight"]
    # a fin: one extra triangle on an existing edge makes that edge non-manifold, its other two edges boundary
    e0, e1 = f[20, 0], f[20, 1]
    fin_v = np.vstack([v, [[3.0, 3.0, 3.0]]])
    fin = topology_metrics(fin_v, np.vstack([f, [[e0, e1, len(v)]]]))
    assert fin["nonmanifold_edges"] == 1 and fin["boundary_edges"] == 2
