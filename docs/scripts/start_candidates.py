"""Each start of the shape gradient's start choice on one mesh phantom: the choice's own facts (residual, stop
reason) and each candidate's Hausdorff distance when forced alone — to see whether the choice kept the best.

    python docs/scripts/start_candidates.py /work/shapes/dev/falconstatue.obj --noise none --seed 0

Each candidate is flowed alone from its start settings in ``methods.shape_gradient.choose.CANDIDATES``
(``prepare(volume, start=...)``); one JSON line per cell. Reads the truth: development only.
"""
from __future__ import annotations

import argparse
import json


def main(argv=None) -> None:
    from bench.metrics import evaluate
    from methods import get_method
    from methods.shape_gradient.choose import CANDIDATES
    from phantoms import add_noise, get_phantom

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--noise", default="none", help="'none' or the Gaussian SNR in dB")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    ph = get_phantom(f"mesh:{args.mesh}")
    vol = ph.volume(n=args.n)
    if args.noise != "none":
        vol, _ = add_noise(vol, "gaussian", float(args.noise), seed=args.seed)
    facts = get_method("shape_gradient").reconstruct(vol).info["start_choice"]
    out = {"cell": f"{args.mesh} {args.noise} {args.seed}", "chosen": facts["chosen"]}
    for name, start in CANDIDATES:
        fact = facts["candidates"].get(name)
        if fact is None or "error" in fact:
            continue
        rec = get_method("shape_gradient").prepare(vol, start=start).run().result()
        m = evaluate(rec.mesh, ph, vol.h)
        out[name] = {"residual_voxels": fact["residual_voxels"], "stop_reason": fact["stop_reason"],
                     "hausdorff_h": round(m["hausdorff_h"], 3), "mean_dist_h": round(m["mean_dist_h"], 4)}
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
