"""Measure the methods' run time at a few small N, the points their cost models
(:meth:`methods.Method.estimate_seconds`) are fitted to, and compare each model with the measurement.

``python -m bench.perf.cost_models [--methods a,b] [--phantoms sphere,bunny] [--n 24,32,48,64] [--out F.jsonl]``

One line of JSON per (method, phantom, N): the crossing cells of the clean volume, the method's wall time
(``method.reconstruct`` alone, in this process, after a warm-up run at N = 16 that pays the one-time
compilation), the model's estimate for the same volume and the load average when the run ended — the
machine is shared, so every figure carries its load.  docs/NOTES.md ("Cost models") holds a run of it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from methods import crossing_cells, get_method
from phantoms import get_phantom

__all__ = ["measure_point", "main"]

DEFAULT_METHODS = ("reach_for_the_spheres", "dual_contouring", "distmesh")


def measure_point(method: str, phantom: str, n: int) -> dict:
    """One measured point: ``{method, phantom, n, crossing_cells, wall_s, estimate_s, load1}``."""
    vol = get_phantom(phantom).volume(n=n)
    m = get_method(method)
    t0 = time.perf_counter()
    m.reconstruct(vol)
    wall = time.perf_counter() - t0
    cells = crossing_cells(vol)
    return {"method": method, "phantom": phantom, "n": n, "crossing_cells": cells, "wall_s": round(wall, 3),
            "estimate_s": m.estimate_seconds(vol.shape, cells), "estimate_n_only_s": m.estimate_seconds(vol.shape),
            "load1": round(os.getloadavg()[0], 2)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench.perf.cost_models", description=__doc__.split("\n\n")[0])
    p.add_argument("--methods", default=",".join(DEFAULT_METHODS))
    p.add_argument("--phantoms", default="sphere,bunny")
    p.add_argument("--n", default="24,32,48,64")
    p.add_argument("--out", default=None, help="also append the lines to this file")
    args = p.parse_args(argv)
    ns = [int(t) for t in args.n.split(",") if t.strip()]
    for method in args.methods.split(","):
        get_method(method).reconstruct(get_phantom("sphere").volume(n=16))   # warm-up: compilation, imports
        for phantom in args.phantoms.split(","):
            for n in ns:
                line = json.dumps(measure_point(method, phantom, n))
                print(line, flush=True)
                if args.out:
                    with open(args.out, "a") as fh:
                        fh.write(line + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
