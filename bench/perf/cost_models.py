"""Measure the methods' run time at a few small N, the points their cost models
(:meth:`methods.Method.estimate_seconds`) are fitted to, and compare each model with the measurement.

``python -m bench.perf.cost_models [--methods a,b] [--phantoms sphere,bunny] [--n 24,32,48,64] [--set k=v,...]
[--out F.jsonl]``; ``--fit F.jsonl [--n-min N] [--per-iteration] [--floor]`` fits the points of a file instead.

One line of JSON per (method, phantom, N): the crossing cells of the clean volume, the method's wall and CPU
time (``method.reconstruct`` alone, in this process, after a warm-up run at N = 16 that pays the one-time
compilation), its iterations, the model's estimate for the same volume and the load average when the run ended.
The models are fitted to the CPU time: on a shared machine the wall time of a single-threaded run grows with the
load, its CPU time much less, and on a quiet machine the two agree.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from methods import crossing_cells, get_method
from phantoms import add_noise, get_phantom

__all__ = ["measure_point", "fit_power_law", "main"]

DEFAULT_METHODS = ("reach_for_the_spheres", "dual_contouring", "distmesh")


def measure_point(method: str, phantom: str, n: int, params: dict | None = None, noise: str = "none") -> dict:
    """One measured point: ``{method, phantom, n, params, noise, crossing_cells, wall_s, cpu_s, iterations,
    estimate_s, load1}`` (a run that raises is recorded with its error); ``noise`` = none or KIND@SNR (seed 0)."""
    vol = get_phantom(phantom).volume(n=n)
    if noise != "none":
        kind, _, snr = noise.partition("@")
        vol = add_noise(vol, kind, float(snr), seed=0)[0]
    m = get_method(method, **(params or {}))
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        its, error = m.reconstruct(vol).info.get("iterations"), None
    except Exception as exc:  # noqa: BLE001 - a diverged run still took its time
        its, error = None, f"{type(exc).__name__}: {exc}"[:160]
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    cells = crossing_cells(vol)
    return {"method": method, "phantom": phantom, "n": n, "params": params or {}, "noise": noise,
            "crossing_cells": cells,
            "wall_s": round(wall, 3), "cpu_s": round(cpu, 3), "iterations": its,
            "estimate_s": m.estimate_seconds(vol.shape, cells), "load1": round(os.getloadavg()[0], 2),
            **({"error": error} if error else {})}


def fit_power_law(points: list[dict], n_min: int = 0, per_iteration: bool = False,
                  floor: bool = False) -> dict | None:
    """Least-squares fit, in log space, of ``t = f + a · (N / 64)^p`` (``f`` = 0 unless ``floor``) over the
    points with N ≥ ``n_min`` (every phantom together; t = the CPU seconds, or per iteration):
    ``{"a": s at N = 64 above the floor, "p", "floor", "points", "worst_ratio": the largest measured / fitted or
    fitted / measured}`` — the :class:`methods.PowerLaw` constants of a method; None with fewer than two sizes."""
    import numpy as np
    from scipy.optimize import least_squares

    pts = [q for q in points if q["n"] >= n_min and not q.get("params") and not q.get("error")
           and (q.get("iterations") or not per_iteration)]          # the default settings' runs only
    if len({q["n"] for q in pts}) < 2:
        return None
    x = np.array([q["n"] for q in pts], float) / 64.0
    y = np.log(np.array([q.get("cpu_s", q["wall_s"]) / (q["iterations"] if per_iteration else 1) for q in pts]))

    def model(c):
        return np.log((np.exp(c[2]) if floor else 0.0) + np.exp(c[0]) * x ** c[1])

    start = np.array([float(np.median(y)), 2.0, float(y.min()) - 1.0])
    c = least_squares(lambda c: model(c) - y, start).x
    return {"a": round(float(np.exp(c[0])), 4), "p": round(float(c[1]), 2),
            "floor": round(float(np.exp(c[2])), 4) if floor else 0.0, "points": len(pts),
            "worst_ratio": round(float(np.exp(np.abs(model(c) - y)).max()), 2)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.perf.cost_models", description=__doc__.split("\n\n")[0])
    p.add_argument("--methods", default=",".join(DEFAULT_METHODS))
    p.add_argument("--phantoms", default="sphere,bunny")
    p.add_argument("--n", default="24,32,48,64")
    p.add_argument("--out", default=None, help="also append the lines to this file")
    p.add_argument("--fit", metavar="F.jsonl", help="measure nothing: fit each method's points in F.jsonl")
    p.add_argument("--n-min", type=int, default=0, help="with --fit: only the points with N >= this")
    p.add_argument("--per-iteration", action="store_true", help="with --fit: fit the CPU seconds per iteration")
    p.add_argument("--floor", action="store_true", help="with --fit: a constant term too (t = f + a N^p)")
    p.add_argument("--set", default="", metavar="K=V,...", help="method parameters (e.g. max_iter=12)")
    p.add_argument("--noise", default="none", metavar="KIND@SNR", help="e.g. gaussian@30 (seed 0)")
    args = p.parse_args(argv)
    if args.fit:
        with open(args.fit) as fh:
            points = [json.loads(line) for line in fh if line.strip()]
        for method in dict.fromkeys(q["method"] for q in points):
            fit = fit_power_law([q for q in points if q["method"] == method], args.n_min, args.per_iteration,
                                args.floor)
            print(json.dumps({"method": method, **(fit or {"fit": "fewer than two sizes"})}))
        return 0
    ns = [int(t) for t in args.n.split(",") if t.strip()]
    params = {k: float(v) if "." in v else int(v) if v.isdigit() else v
              for k, v in (kv.split("=", 1) for kv in args.set.split(",") if kv)}
    for method in args.methods.split(","):
        get_method(method).reconstruct(get_phantom("sphere").volume(n=16))   # warm-up: compilation, imports
        for phantom in args.phantoms.split(","):
            for n in ns:
                line = json.dumps(measure_point(method, phantom, n, params, args.noise))
                print(line, flush=True)
                if args.out:
                    with open(args.out, "a") as fh:
                        fh.write(line + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
