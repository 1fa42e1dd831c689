"""The intersection guard's check (methods/shape_gradient/guard.py): both tests, the local patch check, the
fallback of an unrepairable start, and a clean exit after the guard's thread ran (pymeshlab loaded on the caller's
thread: first loaded inside the guard's thread after the metrics' worker thread had run, it corrupted the heap —
glibc aborted the process at exit, 'malloc_consolidate(): unaligned fastbin chunk detected')."""

from __future__ import annotations

import subprocess
import sys

import numpy as np

from geometry.intersections import self_intersection_pairs
from geometry.sphere import fibonacci_sphere
from methods.shape_gradient.guard import _meshlab_faces, count_intersections


def _sphere_with_a_dent(dent: float):
    """A unit sphere whose vertex nearest the north pole is pushed down by ``dent`` (through the south side
    when dent > 2)."""
    x, f = fibonacci_sphere(600, 1.0)
    x = np.array(x, dtype=float)
    top = int(np.argmax(x[:, 2]))
    x[top, 2] -= dent
    return x, np.asarray(f), top


def test_count_is_the_union_of_both_tests():
    x, f, _ = _sphere_with_a_dent(2.3)
    n, bad = count_intersections(x, f)
    expected = np.union1d(_meshlab_faces(x, f), np.unique(self_intersection_pairs(x, f)))
    assert n > 0 and n == len(bad) and np.array_equal(bad, expected)


def test_the_local_check_finds_what_the_full_check_finds():
    x, f, top = _sphere_with_a_dent(2.3)                 # the pole's fan pierces the south side
    n, bad = count_intersections(x, f)
    n_local, bad_local = count_intersections(x, f, moved=np.array([top]))
    assert n > 0 and n_local == n and np.array_equal(bad_local, bad)
    far = int(np.argmin(x[:, 0]))         # another vertex: its patch (grown by the longest face) never invents a hit
    assert set(count_intersections(x, f, moved=np.array([far]))[1]) <= set(bad)


def test_a_clean_mesh_has_no_intersections_by_either_check():
    x, f, top = _sphere_with_a_dent(0.5)                  # a dent, no piercing
    assert count_intersections(x, f)[0] == 0
    assert count_intersections(x, f, moved=np.array([top]))[0] == 0


def test_the_repair_rechecks_its_patch_only_and_ends_as_a_full_recheck_would(monkeypatch):
    # a shallow piercing (the pole's fan just through the south side) the smoothing can clear
    import methods.shape_gradient.guard as guard
    from geometry.operators import MeshOperators

    x, f, _ = _sphere_with_a_dent(2.05)
    ops = MeshOperators(f, len(x))
    n, bad = count_intersections(x, f)
    assert n > 0
    local = guard.repair_intersections(ops, x, bad)
    full_check = guard.count_intersections
    monkeypatch.setattr(guard, "count_intersections", lambda x, faces, moved=None: full_check(x, faces))
    full = guard.repair_intersections(ops, x, bad)
    assert local is not None and full is not None
    assert np.array_equal(local, full) and count_intersections(local, f)[0] == 0


def test_an_unrepairable_remeshed_start_falls_back_to_the_start_as_grown(monkeypatch):
    # the remesher returns a mesh with a vertex pushed through the surface and the repair gives up: with no
    # earlier safe mesh to roll back to, the flow keeps the start as grown (intersection-free), and the stop tests
    # wait for a remesh (marching cubes' slivers move slowly: the noisy bunny at 30 dB stopped at iteration 3)
    import methods.shape_gradient.flow as flow_module
    from methods.shape_gradient import ShapeGradient
    from phantoms import get_phantom

    def pierced(x, f, edge_length, iterations, closed=False, keep=None):
        x = np.array(x, dtype=float)
        top = int(np.argmax(x[:, 2]))
        x[top, 2] -= 1.2 * (x[:, 2].max() - x[:, 2].min())          # through the far side
        return x, np.asarray(f)
    monkeypatch.setattr(flow_module, "remesh", pierced)
    monkeypatch.setattr(flow_module, "repair_intersections", lambda ops, x, bad: None)
    vol = get_phantom("sphere").volume(n=24)
    method = ShapeGradient(max_iter=4, remesh_every=3, sign_guard=False)
    grown = method.prepare(vol).snapshots[0]
    flow = method.prepare(vol)
    stats = flow.stats
    assert stats.remesh_refused == 1 and stats.intersections[0][1] > 0 and tuple(stats.intersections[-1]) == (0, 0)
    assert np.array_equal(flow.state.x, grown[0]) and flow.convergence.held
    flow.run()
    assert count_intersections(flow.state.x, flow.ops.faces)[0] == 0
    assert stats.remeshes and not flow.convergence.held      # the remesh at iteration 3 released the stop tests


_CHILD = """
import importlib.util, warnings; warnings.filterwarnings("ignore")
from pathlib import Path
from bench.metrics import evaluate
from methods import get_method
from methods.shape_gradient.guard import count_intersections
from phantoms import add_noise, get_phantom
mesh = Path(importlib.util.find_spec("pymeshlab").submodule_search_locations[0]) / "tests/sample_meshes/bone.ply"
ph = get_phantom(f"mesh:{mesh}")
vol, _ = add_noise(ph.volume(n=64), "gaussian", 40.0, seed=0)
r = get_method("marching_cubes").reconstruct(vol)
evaluate(r.mesh, ph, vol.h, n_samples=100_000)
print(count_intersections(r.mesh.vertices, r.mesh.faces)[0])
"""


def test_scoring_then_the_guards_thread_exits_cleanly():
    # a fresh process: pymeshlab not yet loaded, the metrics' distance query run in its worker thread first
    done = subprocess.run([sys.executable, "-c", _CHILD], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "0"
