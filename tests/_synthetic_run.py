"""A synthetic run folder of many cells (a dataset grid of small meshes), written through the store's own
functions: for the report's scaling tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import json

from bench.run.integrity import seal
from bench.run.row import ResultRow
from bench.run.store import CELLS_DIR, write_json
from bench.run.results import write_results_csv

METHODS = ("marching_cubes", "mc_taubin", "poisson", "distmesh", "shape_gradient")


def _mesh(rng, n_sub: int = 2):
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=n_sub, radius=1.0)
    v = np.asarray(m.vertices) * (1 + 0.02 * rng.standard_normal((len(m.vertices), 1)))
    return v.astype(np.float32), np.asarray(m.faces, np.int32)


def write_synthetic_run(out: Path, n_shapes: int = 100, seeds: int = 5, noise=("none", "gaussian"),
                        sealed: bool = False, phantom: str = "shape_{:03d}") -> int:
    """``n_shapes`` × noise settings × ``seeds`` (clean: one) × 5 methods cells; returns the number of cells.
    ``sealed``: each record carries its checksum, as the runner writes it (bench.run.integrity.seal);
    ``phantom``: the phantoms' names, formatted with the shape's number (the cell ids keep ``shape_NNN``)."""
    rng = np.random.default_rng(0)
    out = Path(out)
    (out / CELLS_DIR).mkdir(parents=True, exist_ok=True)
    rows, cells, records = [], [], {}
    v, f = _mesh(rng)
    for s in range(n_shapes):
        for kind in noise:
            for seed in (range(1) if kind == "none" else range(seeds)):
                for k, method in enumerate(METHODS):
                    cid = f"shape_{s:03d}_sdf_n32_{kind}_s{seed}_{method}"
                    h = 0.3 + 0.2 * k + 0.1 * rng.random() + (0.3 if kind != "none" else 0.0)
                    row = {"cell_id": cid, "phantom": phantom.format(s), "variant": "sdf", "N": 32, "noise": kind,
                           "snr_requested": None if kind == "none" else 30.0, "snr_achieved": None,
                           "seed": seed, "method": method, "label": method, "parameters": "{}",
                           "source": f"mesh:/data/shapes/shape_{s:03d}.obj", "h": 0.16, "has_truth": True,
                           "hausdorff_h": h, "hausdorff": 0.16 * h, "mean_dist_h": h / 5, "sdf_rms_h": h / 4,
                           "phi_mean_h": h / 10, "roughness_deg": 5 + k, "fscore@h": 1 - h / 10, "euler": 2,
                           "components": 1, "self_intersections": 0, "watertight": True, "wall_s": 0.01 * (k + 1),
                           "iterations": None, "energy_final": None, "stop_reason": None, "peak_mem_mb": 50.0,
                           "flags": "not_converged" if method == "shape_gradient" and seed == 1 else "",
                           "status": "ok" if (s + k) % 97 else "invalid", "error": ""}
                    cell = {"cell_id": cid, "phantom": row["phantom"], "variant": "sdf", "n": 32, "extent": 2.5,
                            "noise": kind, "snr_requested": row["snr_requested"], "seed": seed, "method": method,
                            "label": method, "params": {}, "n_samples": 1000, "imports": []}
                    # the store's layout (bench/run/store.py: save_cell), written without its fsyncs for speed
                    np.savez(out / CELLS_DIR / f"{cid}.npz", vertices=v * (1 + 0.01 * k), faces=f,
                             H=np.ones(len(v), np.float32))
                    records[cid] = {"row": row, "cell": cell, "traceback": None,
                                    "artifacts": ["H", "faces", "vertices"], "code": None}
                    if sealed:
                        records[cid] = seal(records[cid], out / CELLS_DIR / f"{cid}.npz")
                    (out / CELLS_DIR / f"{cid}.json").write_text(json.dumps(records[cid]))
                    rows.append(row)
                    cells.append(cell)
    write_results_csv(out, [c["cell_id"] for c in cells],
                      {cid: {**rec, "row": ResultRow.from_dict(rec["row"])} for cid, rec in records.items()})
    write_json(out / "run.json", {"config": {"name": "synthetic", "grid": {"extent": 2.5}},
                                  "cells": {"total": len(rows)}})
    return len(rows)
