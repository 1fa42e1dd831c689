"""Sharp-feature metrics (bench/metrics/features.py): edge_chamfer / edge_fscore against the exact creases."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from bench.metrics import evaluate
from bench.metrics.features import edge_samples, truth_edge_samples
from phantoms import MeshPhantom, get_phantom

H = 0.05
R, HH = 0.4, 1.0          # the cylinder phantom: radius 0.4, |z| <= 1


def _refined(prof, step: float) -> np.ndarray:
    """The polyline with points inserted so no segment is longer than ``step`` (well-shaped triangles)."""
    out = [prof[0]]
    for p, q in zip(prof[:-1], prof[1:]):
        k = max(1, math.ceil(math.dist(p, q) / step))
        out += [tuple(np.add(p, np.subtract(q, p) * (i / k))) for i in range(1, k + 1)]
    return np.array(out)


def revolved_cylinder(rho: float = 0.0, n_arc: int = 16, sections: int = 96) -> trimesh.Trimesh:
    """The phantom cylinder as a surface of revolution; rims rounded with fillet radius rho (0: sharp rims);
    profile points every ≤ 0.025 and 96 sections (≤ 0.026 apart on the side), so the triangles are well shaped."""
    prof = [(0.0, -HH)]
    if rho == 0:
        prof += [(R, -HH), (R, HH)]
    else:
        for c, a0 in (((R - rho, -HH + rho), -math.pi / 2), ((R - rho, HH - rho), 0.0)):
            a = np.linspace(a0, a0 + math.pi / 2, n_arc)
            prof += list(zip(c[0] + rho * np.cos(a), c[1] + rho * np.sin(a)))
    prof.append((0.0, HH))
    mesh = trimesh.creation.revolve(_refined(prof, 0.025), sections=sections)
    assert mesh.is_watertight and mesh.volume > 0
    return mesh


@pytest.fixture(scope="module")
def cylinder():
    return get_phantom("cylinder")


@pytest.mark.parametrize("name", ["cylinder", "fused_spheres"])
def test_truth_edge_samples_lie_on_the_exact_creases_and_are_dense(name):
    ph = get_phantom(name)
    t = truth_edge_samples(ph, H)
    assert len(t) >= 40 * ph.crease_length / H
    assert np.all(ph.truth(t).crease_distance < 1e-12)       # on a rim / the crease circle
    # evenly spaced by arc length: every nearest-neighbour gap is the chord of one step along its circle
    circles = 2 if name == "cylinder" else 1
    radius = R if name == "cylinder" else ph.crease_radius
    gaps, _ = cKDTree(t).query(t, k=2)
    np.testing.assert_allclose(gaps[:, 1], 2 * radius * np.sin(np.pi * circles / len(t)), rtol=1e-9)


def test_smooth_phantom_has_no_edge_metrics():
    out = evaluate(trimesh.creation.icosphere(3), get_phantom("sphere"), H, n_samples=5000)
    assert math.isnan(out["edge_chamfer"]) and math.isnan(out["edge_fscore"])


def test_exact_cylinder_mesh_finds_its_rims(cylinder):
    out = evaluate(revolved_cylinder(), cylinder, H, n_samples=20_000)
    assert out["edge_fscore"] == 1.0
    # edge samples are the points within h of a rim (on the cap or the side): mean distance below h/2
    assert out["edge_chamfer"] < 0.5 * H and out["edge_chamfer_h"] == pytest.approx(out["edge_chamfer"] / H)


def test_rounded_rims_score_worse_than_sharp_ones(cylinder):
    sharp = evaluate(revolved_cylinder(), cylinder, H, n_samples=20_000)
    rounded = evaluate(revolved_cylinder(rho=H / 2), cylinder, H, n_samples=20_000)
    rounder = evaluate(revolved_cylinder(rho=H), cylinder, H, n_samples=20_000)
    assert sharp["edge_chamfer"] < rounded["edge_chamfer"] < rounder["edge_chamfer"]
    assert sharp["edge_fscore"] >= rounded["edge_fscore"] > rounder["edge_fscore"]
    # a fillet of 3h leaves no sample pair within h whose normals differ by 60°: the rims are gone
    gone = evaluate(revolved_cylinder(rho=3 * H), cylinder, H, n_samples=20_000)
    assert gone["edge_chamfer"] == math.inf and gone["edge_fscore"] == 0.0


def test_edge_samples_use_the_60_degree_threshold():
    """Two half-planes meeting at a fold: samples near the fold are edge samples iff the fold exceeds 60°."""
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (20000, 2))
    for angle, expect in ((50.0, False), (70.0, True)):
        a = math.radians(angle)
        n_left, n_right = np.array([0.0, 0.0, 1.0]), np.array([math.sin(a), 0.0, math.cos(a)])
        pts = np.column_stack([u[:, 0], u[:, 1], np.zeros(len(u))])
        normals = np.where((u[:, 0] < 0)[:, None], n_left, n_right)
        e = edge_samples(pts, normals, area=4.0, h=0.05)
        assert (len(e) > 0) == expect
        if expect:
            assert np.abs(e[:, 0]).max() <= 0.05                # only within h of the fold


def test_mesh_phantom_creases_are_its_sharp_edges():
    box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    ph = MeshPhantom(box.vertices, box.faces, normalize=False)
    assert ph.crease_length == pytest.approx(12.0)            # the 12 cube edges; face diagonals are flat
    out = evaluate(box, ph, 0.05, n_samples=50_000)
    assert out["edge_fscore"] == 1.0 and out["edge_chamfer"] < 0.025
