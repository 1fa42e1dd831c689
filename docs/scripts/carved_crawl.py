"""The carved candidate of the start choice flowed alone on one suite phantom, iteration by iteration: energy, the
line search's trial move, the largest normal move actually made, the relative energy change, vertices, held
vertex-iterations — to see why a held flow does or does not stop.

    python docs/scripts/carved_crawl.py sphere --n 96 --noise none
    python docs/scripts/carved_crawl.py fused_spheres --n 96 --usual      # the usual start, for comparison

Prints the process time and the stop first, then one line per iteration.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None) -> None:
    from methods import get_method
    from methods.shape_gradient.choose import CANDIDATES
    from phantoms import add_noise, get_phantom

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("phantom")
    ap.add_argument("--n", type=int, default=96)
    ap.add_argument("--noise", default="none", help="'none', or 'gaussian' / 'uniform' at the paper's SNR")
    ap.add_argument("--usual", action="store_true", help="the usual start instead of the carved one")
    ap.add_argument("--max-iter", type=int, default=300)
    args = ap.parse_args(argv)
    ph = get_phantom(args.phantom)
    vol = ph.volume(n=args.n)
    if args.noise != "none":
        vol, _ = add_noise(vol, args.noise, ph.paper_snr_db, seed=0)
    carved = None if args.usual else dict(CANDIDATES)["carved"]
    t0 = time.process_time()
    flow = get_method("shape_gradient", max_iter=args.max_iter).prepare(vol, start=carved)
    x0, e0, rows = flow.state.x.copy(), flow.state.E, []
    while True:
        going = flow.step()
        x = flow.state.x
        made = (float(np.abs(np.einsum("vd,vd->v", x - x0, flow.state.geo.vertex_normals)).max()) / flow.h
                if x.shape == x0.shape else float("nan"))                   # nan: a remesh changed the vertices
        trial = flow.stats.moves[-1] / flow.h if flow.stats.moves else float("nan")
        held = flow.carve.held if flow.carve else 0
        rows.append(f"{flow.iteration} E={flow.state.E:.4e} trial={trial:.4f} made={made:.4f} "
                    f"dE/E={abs(e0 - flow.state.E) / abs(e0):.1e} V={len(x)} held={held}")
        x0, e0 = x.copy(), flow.state.E
        if not going:
            break
    print(f"cpu {time.process_time() - t0:.1f} s; {flow.stop}: {flow.message}")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
