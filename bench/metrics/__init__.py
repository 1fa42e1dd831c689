"""Every number the suite reports about a reconstructed mesh (definitions: ``docs/METRICS.md``).

>>> from phantoms import get_phantom
>>> from bench.metrics import evaluate, METRIC_NAMES
>>> row = evaluate(mesh, get_phantom("ellipsoid"), spacing=vol.spacing[0])      # doctest: +SKIP
>>> row = evaluate(mesh, None, spacing=h)          # truth-free subset for user volumes  # doctest: +SKIP

:func:`evaluate` computes the metrics the same way for every method, from the output mesh and the
phantom's exact ground truth:

* distances (``distance.py``): recon → truth exact via the phantom, truth → recon exact point-to-triangle
  (geometry/closest.py); maxima over all points, percentiles / means / F-score over seeded area-uniform samples;
* curvature and smoothness (``curvature.py``): the shared paraboloid-fit estimator over a 2h neighbourhood;
* topology, quality, self-intersections and SIF % (``topology.py``);
* sharp-feature accuracy ``edge_chamfer`` / ``edge_fscore`` (``features.py``) and the volumetric ``iou``
  (``volume.py``);
* the papers' SDF energy over the grid's points (``sdf_energy.py``);
* data fidelity against the volume the method was given — SDF agreement, |φ| on the mesh, sign agreement
  (``fidelity.py``) and the topology of its inside set against the mesh's (``data_topology.py``) — truth-free,
  so also for user scans.

The mesh is evaluated as given except that faces with a repeated vertex index (no area, no real edges)
and unreferenced vertices are dropped first (``n_vertices`` / ``n_faces`` report the mesh as given).  The
cleaned mesh becomes one :class:`geometry.mesh.ScoredMesh` that every metric family reads, so its face normals
and areas, edges, edge → face adjacency, vertex normals and signed volume are each computed once.
``iterations``, ``energy_final``, ``wall_s``, ``peak_mem_mb`` are in :data:`METRIC_NAMES` for the
runner's columns but are filled by the cell runner (:mod:`bench.run.cell`, :func:`bench.run.cost.measure`),
not here.

The compiled distance query (which releases the GIL) runs in one worker thread while numpy computes the rest
(:data:`PARALLEL_DISTANCE`): the two phases cost about the same, so this nearly halves the wall time
(``tests/benchmarks/test_bench_metrics.py`` times it).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from geometry.mesh import ScoredMesh
from phantoms import InputError

from .curvature import (
    CONSTANT_CURVATURE,
    constant_curvature_value,
    curvature_metrics,
    roughness_deg,
    vertex_curvature,
)
from .distance import (
    DISTANCE_LIBRARY,
    distance_metrics,
    point_mesh_distance,
    sample_mesh_surface,
)
from .features import edge_metrics
from .data_topology import data_topology_metrics, digital_topology
from .fidelity import band_query, fidelity_metrics, mesh_inside
from .registry import METRICS, Metric
from .sdf_energy import energy_distances, energy_query, sdf_energy
from .volume import iou
from .topology import (
    compact,
    drop_degenerate_index_faces,
    quality_metrics,
    self_intersection_pairs,
    sif_pct,
    topology_metrics,
    triangle_angles,
)

__all__ = [
    "evaluate", "METRICS", "Metric", "METRIC_NAMES", "TRUTH_FREE_NAMES", "FIDELITY_NAMES", "DISTANCE_NAMES",
    "RUNNER_NAMES", "PARALLEL_DISTANCE",
    "sample_mesh_surface", "point_mesh_distance", "self_intersection_pairs", "triangle_angles",
    "vertex_curvature", "constant_curvature_value", "CONSTANT_CURVATURE", "DISTANCE_LIBRARY",
]

#: distances in world units; each also appears divided by the grid spacing as ``<name>_h``
DISTANCE_NAMES = [k for k, m in METRICS.items() if m.kind == "distance"]

#: keys evaluate returns when no truth is given (user volumes); the fidelity ones need the volume
TRUTH_FREE_NAMES = [k for k, m in METRICS.items() if m.kind in ("truth_free", "fidelity")]
#: the data-fidelity metrics (against the volume φ; docs/METRICS.md)
FIDELITY_NAMES = [k for k, m in METRICS.items() if m.kind == "fidelity"]

#: filled by the runner, not by evaluate
RUNNER_NAMES = [k for k, m in METRICS.items() if m.kind == "runner"]

#: every registered metric, in registry order (the results.csv columns)
METRIC_NAMES = list(METRICS)


def evaluate(mesh, truth, spacing: float, *, volume=None, n_samples: int = 100_000, seed: int = 0,
             crease_band: float = 0.1, timings: dict | None = None, vertex_H: dict | None = None,
             truth_points: np.ndarray | None = None, clean=None, details: dict | None = None) -> dict:
    """All the metrics of ``docs/METRICS.md`` of ``mesh`` against the phantom ``truth`` (or the truth-free subset).

    Parameters
    ----------
    mesh : trimesh.Trimesh
        The reconstructed surface, world coordinates.
    truth : phantoms.Phantom or None
        The phantom the volume was sampled from (``phantoms.get_phantom(name)``); None for a user volume
        without ground truth → only :data:`TRUTH_FREE_NAMES`.
    spacing : float
        Grid spacing h: the F-score threshold, the unit of the ``*_h`` distances and the curvature
        neighbourhood radius (2h).
    volume : phantoms.Volume, optional
        The volume the method was given; with it the data-fidelity metrics (:data:`FIDELITY_NAMES`) are
        computed (NaN without it).
    n_samples : int
        Area-uniform samples on each of the two surfaces (≥ 100,000 for reported results).
    seed : int
        Seed of both sample sets (same seed → same numbers).
    crease_band : float
        Vertices whose closest true point is closer than this to a crease/rim are left out of the
        curvature errors, of ``H_std`` and (edges touching them) of ``roughness_deg``.
    timings : dict, optional
        Filled with the seconds spent per phase (sampling, distances, curvature, ...).
    vertex_H : dict, optional
        Filled with ``"H"`` and ``"K"``: the per-vertex mean and Gaussian curvature the curvature metrics used,
        one value per vertex of ``mesh`` as given (NaN for a vertex no face uses) — for pictures and the report,
        so nobody fits them twice.
    truth_points : numpy.ndarray, shape (n_samples, 3), optional
        ``truth.sample_surface(n_samples, seed)[0]`` computed before (a cache: the same for every mesh
        scored against this truth).
    clean : phantoms.Volume, optional
        The clean level set S of the grid (before noise or a degradation; the cell runner passes it):
        ``sdf_energy`` reads |S| at its grid points (NaN without it: the noisy φ would score the noise).
    details : dict, optional
        Filled with ``"topology_vs_data"``: the differences between the topology of the volume's inside set and
        the mesh's, ``; ``-joined (empty: none; :mod:`bench.metrics.data_topology`); absent without a volume.

    Returns
    -------
    dict
        The keys of :data:`METRIC_NAMES` except :data:`RUNNER_NAMES` (plain Python floats, ints, bools; NaN
        where a metric is undefined, e.g. ``H_std`` on the ellipsoid); without a truth the keys of
        :data:`TRUTH_FREE_NAMES`.

    Raises
    ------
    InputError
        A mesh without faces, non-finite vertices, faces indexing missing vertices, a bad spacing.
    """
    return _evaluate(mesh, truth, spacing, volume=volume, n_samples=n_samples, seed=seed, crease_band=crease_band,
                     timings=timings, vertex_H=vertex_H, truth_points=truth_points, clean=clean, details=details)


def _check_inputs(mesh, spacing, n_samples, crease_band):
    try:
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        faces = np.asarray(mesh.faces, dtype=np.int64)
    except AttributeError:
        raise InputError(f"evaluate needs a mesh with .vertices and .faces; got {type(mesh).__name__}") from None
    if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"mesh must have vertices (V, 3) and faces (F, 3); got {vertices.shape}, {faces.shape}")
    if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError("mesh faces index vertices that do not exist")
    if not np.isfinite(vertices).all():
        raise InputError("mesh has non-finite vertex coordinates")
    h = float(spacing)
    if not (math.isfinite(h) and h > 0):
        raise InputError(f"spacing must be a positive number; got {spacing!r}")
    if int(n_samples) != n_samples or n_samples < 1:
        raise InputError(f"n_samples must be a positive integer; got {n_samples!r}")
    if not (crease_band >= 0):
        raise InputError(f"crease_band must be >= 0; got {crease_band!r}")
    return vertices, faces, h


#: run the distance query in a worker thread, overlapping the numpy phases (same results)
PARALLEL_DISTANCE = True


def _start(fn, *args):
    """Run ``fn(*args)`` in a worker thread (or now, if PARALLEL_DISTANCE is off); returns a function
    that waits and gives ``(result, seconds fn took)``, re-raising fn's exception."""
    box: dict = {}

    def work():
        t0 = time.perf_counter()
        try:
            box["result"] = fn(*args)
        except BaseException as exc:  # re-raised in the caller's thread
            box["error"] = exc
        box["seconds"] = time.perf_counter() - t0

    if PARALLEL_DISTANCE:
        th = threading.Thread(target=work, name="bench-metrics-distance", daemon=True)
        th.start()
    else:
        th = None
        work()

    def wait():
        if th is not None:
            th.join()
        if "error" in box:
            raise box["error"]
        return box["result"], box["seconds"]

    return wait


def _distances(true_pts, band_pts, mesh, grid_pts=None):
    """(truth → mesh distances or None, band samples → mesh distances or None, SDF-energy grid points → mesh
    distances or None): the worker thread's share."""
    d_grid = None if grid_pts is None else energy_distances(grid_pts, mesh.vertices, mesh.faces)
    parts = [p for p in (true_pts, band_pts) if p is not None]
    if not parts:
        return None, None, d_grid
    d = point_mesh_distance(np.concatenate(parts) if len(parts) > 1 else parts[0], mesh.vertices, mesh.faces)
    n_true = len(true_pts) if true_pts is not None else 0
    return (d[:n_true] if true_pts is not None else None), (d[n_true:] if band_pts is not None else None), d_grid


def _energy_grid(truth, clean, seed):
    """(S at the SDF energy's grid points, those points) or (None, None): only with a truth and a clean grid."""
    if truth is None or clean is None:
        return None, None
    idx, pts = energy_query(clean, seed)
    return clean.values.reshape(-1)[idx], pts


def _evaluate(mesh, truth, spacing, *, volume=None, n_samples=100_000, seed=0, crease_band=0.1, timings=None,
              vertex_H=None, truth_points=None, clean=None, details=None) -> dict:
    """:func:`evaluate`, optionally recording the seconds spent per phase in ``timings``."""
    t = time.perf_counter()
    tm = timings if timings is not None else {}

    def lap(name):
        nonlocal t
        now = time.perf_counter()
        tm[name] = tm.get(name, 0.0) + now - t
        t = now

    vertices, faces, h = _check_inputs(mesh, spacing, n_samples, crease_band)
    n_samples = int(n_samples)
    out = {"n_vertices": int(len(vertices)), "n_faces": int(len(faces))}
    f_all = drop_degenerate_index_faces(faces)
    if len(f_all) == 0:
        raise InputError("mesh has no (non-degenerate) faces")
    V, F, kept = compact(vertices, f_all)
    scored = ScoredMesh(V, F)
    lap("prepare")

    true_pts = band = band_pts = None
    if truth is not None:
        true_pts = truth.sample_surface(n_samples, seed)[0] if truth_points is None else truth_points
        if len(true_pts) != n_samples:
            raise InputError(f"truth_points holds {len(true_pts)} points, not n_samples = {n_samples}")
        lap("truth_samples")
    if volume is not None:
        band, band_pts = band_query(volume, seed)
        lap("fidelity_band")
    S_grid, grid_pts = _energy_grid(truth, clean, seed)
    # truth/band/grid -> recon distances (compiled, GIL released) run in a worker thread while numpy does the rest
    pending = _start(_distances, true_pts, band_pts, scored, grid_pts)
    data_topology = digital_topology(volume.inside_raw) if volume is not None else None
    lap("data_topology")

    out.update(topology_metrics(scored))
    out.update(quality_metrics(scored))
    lap("topology_quality")
    pairs = self_intersection_pairs(V, F)
    out["self_intersections"] = int(len(pairs))
    out["sif_pct"] = sif_pct(pairs, len(F))
    lap("self_intersections")

    H, K, _ = vertex_curvature(scored, None, h, outward=scored.outward)
    if vertex_H is not None:
        for key, values in (("H", H), ("K", K)):
            vertex_H[key] = np.full(len(vertices), np.nan)
            vertex_H[key][kept] = values
    lap("curvature_fit")

    def fidelity(pts):
        (_, d_band, _), tm["distances (worker)"] = pending()
        lap("distances (wait)")
        if volume is None:
            out.update({k: math.nan for k in FIDELITY_NAMES})
            lap("fidelity")
        else:
            enclosed = mesh_inside(scored, None, volume)
            out.update(fidelity_metrics(scored, None, volume, pts, band, d_band, inside=enclosed))
            lap("fidelity")
            columns, detail = data_topology_metrics(scored, None, volume, enclosed, data_topology)
            out.update(columns)
            if details is not None:
                details["topology_vs_data"] = detail
            lap("data_topology")

    if truth is None:
        out.update(curvature_metrics(H, K))
        out["roughness_deg"] = roughness_deg(scored)
        lap("roughness")
        fidelity(sample_mesh_surface(scored, None, n_samples, seed)[0])
        return {k: out[k] for k in TRUTH_FREE_NAMES}

    tv = truth.truth(V)
    lap("truth_vertices")
    out.update(curvature_metrics(H, K, tv, truth, crease_band))
    out["roughness_deg"] = roughness_deg(scored, vertex_ok=tv.crease_distance >= crease_band)
    lap("curvature_metrics_roughness")

    pts, fi = sample_mesh_surface(scored, None, n_samples, seed)
    ts = truth.truth(pts)
    lap("recon_to_truth")
    d_tr, _, d_grid = pending()[0]
    out["sdf_energy"] = sdf_energy(S_grid, d_grid) if d_grid is not None else math.nan
    fidelity(pts)
    fn = scored.face_normals
    out.update(distance_metrics(ts.distance, float(max(tv.distance.max(), ts.distance.max())), d_tr, h,
                                fn[fi], ts.normal))
    lap("distance_stats")
    out.update(edge_metrics(pts, fn[fi], scored.area, truth, h))
    out["edge_chamfer_h"] = out["edge_chamfer"] / h
    lap("edges")
    out["iou"] = iou(scored, None, truth, h, true_pts, seed=seed)
    lap("iou")
    true_volume = getattr(truth, "solid_volume", None)
    out["volume_err_pct"] = (100.0 * (float(scored.signed_volume) - true_volume) / true_volume
                             if true_volume else math.nan)
    return {k: out[k] for k in METRIC_NAMES if k in out}
