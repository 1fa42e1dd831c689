"""Warm the local executor's fork server once, so that no cell pays the first-call costs again.

Every cell runs in a fresh process forked from a server that preloaded the suite.  A fresh process still pays,
at its first call of each step, for what Python and numba do lazily: numba's typing context and the machine
code of each compiled kernel (loaded from the on-disk cache), the modules imported inside functions, scipy's
and scikit-image's lazily loaded parts — more than the whole method on most cells of the paper's grid.

Importing this module runs :func:`warm`: the steps of a cell on a tiny volume (N = 24) and on a mesh big enough
(≥ :data:`geometry.compiled.MIN_SIZE` faces) for the compiled kernels, in the fork server, before it forks the
first worker.  Nothing that starts threads runs here (pymeshlab's OpenMP/TBB, the metrics' worker thread): a
process forked after that could deadlock in its thread pool.  Importing pymeshlab, gpytoolbox or pyamg starts
none (their pools start at their first parallel call), so the libraries the preloaded methods import lazily
(:data:`PRELOADED_METHODS`' :attr:`methods.Method.imports`) are imported here, and no cell imports them again
(tests/test_bench_run_warmup.py checks, in a fresh process, that these imports start no thread).  Any error is
swallowed: warming is an optimisation, never a reason for a run to fail.

A method's own one-off costs are its :meth:`methods.Method.warm_up`, which :func:`bench.run.cell.run_cell`
calls in the cell's process before timing ``reconstruct`` — not here: a plug-in's warm-up may start threads
(a parallel numba kernel), and only the grid's methods should pay for it.
"""

from __future__ import annotations

import time

__all__ = ["warm", "WARM_SECONDS", "PRELOADED_METHODS", "method_imports"]

#: seconds the last :func:`warm` took (None: it failed)
WARM_SECONDS: float | None = None

#: the methods whose lazily imported libraries (:attr:`methods.Method.imports`, :attr:`methods.Method.requires`)
#: the fork server imports: those of the paper's grid, whose imports start no thread
PRELOADED_METHODS = ("marching_cubes", "mc_taubin", "distmesh", "poisson", "shape_gradient")


def method_imports() -> list[str]:
    """The modules of :data:`PRELOADED_METHODS`' ``imports`` and ``requires``, each once, in order."""
    from methods import get_method

    names: list[str] = []
    for name in PRELOADED_METHODS:
        method = get_method(name)
        names += [m for m in (*getattr(method, "requires", {}), *getattr(method, "imports", ())) if m not in names]
    return names


def _metrics_without_threads(mesh, ph, h: float) -> None:
    """The metric steps of :func:`bench.metrics.evaluate` (the distance query here in this thread; evaluate runs
    it in a worker thread)."""
    import numpy as np

    from bench.metrics.curvature import curvature_metrics, roughness_deg, vertex_curvature
    from bench.metrics.distance import distance_metrics, point_mesh_distance, sample_mesh_surface
    from bench.metrics.features import edge_metrics
    from bench.metrics.sdf_energy import energy_distances
    from bench.metrics.topology import quality_metrics, self_intersection_pairs, sif_pct, topology_metrics
    from geometry import face_normals

    V, F = np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)
    fn = face_normals(V, F)
    topology_metrics(V, F)
    quality_metrics(V, F)
    sif_pct(self_intersection_pairs(V, F), len(F))
    H, K, _ = vertex_curvature(V, F, h)
    tv = ph.truth(V)
    curvature_metrics(H, K, tv, ph, 0.1)
    roughness_deg(V, F, fn, vertex_ok=tv.crease_distance >= 0.1)
    pts, fi = sample_mesh_surface(V, F, 2000, 0)
    point_mesh_distance(pts, V, F)
    energy_distances(pts * 3.0, V, F)
    ts = ph.truth(pts)
    distance_metrics(ts.distance, float(ts.distance.max()), ts.distance, h, fn[fi], ts.normal)
    edge_metrics(pts, fn[fi], 1.0, ph, h)
    ph.sample_surface(2000, 0)


def warm() -> float | None:
    """Run the first calls of a cell's steps in this process; the seconds it took (None if a step failed)."""
    global WARM_SECONDS
    t0 = time.perf_counter()
    try:
        import importlib

        for module in method_imports():         # what run_warm_up would import in every cell
            try:
                importlib.import_module(module)
            except ImportError:                 # an optional library: the method says so itself
                pass
        import trimesh

        from bench.metrics.validity import check_mesh
        from methods import get_method
        from phantoms import add_noise, get_phantom

        import numpy as np

        from phantoms import mask_to_sdf

        mask_to_sdf(np.pad(np.ones((3, 3, 3), bool), 2))        # a user mask's distance transform (compiled)
        get_phantom("ellipsoid").truth([[0.3, 0.2, 0.1]])     # its closest-point root find is compiled
        ph = get_phantom("sphere")
        vol = ph.volume(n=24)
        noisy, _ = add_noise(vol, "gaussian", 40.0, seed=0)
        mc = get_method("marching_cubes").reconstruct(vol).mesh
        check_mesh(mc, vol, given=noisy)
        _metrics_without_threads(mc, ph, vol.h)
        big = trimesh.creation.icosphere(subdivisions=5)        # 10,242 vertices: big enough for the kernels
        _metrics_without_threads(big, ph, 0.05)
        # (the genus-0 start is remeshed and checked by MeshLab, in a thread: not here)
        for params in ({"preset": "paper", "max_iter": 3}, {"preset": "paper+fixes", "max_iter": 3, "guard": False}):
            get_method("shape_gradient", **params).reconstruct(noisy)
            get_method("shape_gradient", **params).reconstruct(vol)
        get_method("distmesh", max_iter=3).reconstruct(vol)
    except Exception:  # warming is an optimisation; the cells report their own errors
        WARM_SECONDS = None
        return None
    WARM_SECONDS = time.perf_counter() - t0
    return WARM_SECONDS


warm()
