"""Numbers and options at and past their limits: non-finite numbers where an integer is expected (cause 7), TOML
nested thousands of levels (8), grids too large to expand (10), command-line errors (14) and options that were
silently ignored or coerced (16).  Every one is exit 2 with one line naming the option, before any work."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .core import Case, Ctx, exits_ok, one_line

BASE_TOML = """
[grid]
phantoms = ["sphere"]
n = [16]
noise = [{ kind = "none" }]
[[methods]]
name = "marching_cubes"
"""


def images(ctx: Ctx) -> Path:
    """A mask, a label map and an intensity image of a ball (.npz), made once; returns their folder."""
    def make() -> Path:
        d = ctx.root / "inputs"
        d.mkdir(exist_ok=True)
        idx = np.stack(np.meshgrid(*[np.arange(16)] * 3, indexing="ij"), axis=-1)
        r = np.sqrt(((idx - 7.5) ** 2).sum(-1))
        ball = (r < 5).astype(np.uint8)
        np.savez(d / "mask.npz", values=ball, origin=np.zeros(3), spacing=np.ones(3))
        np.savez(d / "labels.npz", values=ball + (r < 2), origin=np.zeros(3), spacing=np.ones(3))
        np.savez(d / "ct.npz", values=1000.0 * np.clip(6 - r, 0, 1), origin=np.zeros(3), spacing=np.ones(3))
        np.savez(d / "sdf.npz", values=r - 5.0, origin=np.zeros(3), spacing=np.ones(3))
        return d
    return ctx.once("inputs.images", make)


def toml(ctx: Ctx, tag: str, text: str) -> Path:
    path = ctx.root / "inputs" / f"{tag}.toml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(text)
    return path


def dry(ctx: Ctx, tag: str, text: str, timeout: float = 60):
    """``run --config`` on ``text`` with --dry-run."""
    return ctx.bench("run", "--config", str(toml(ctx, tag, text)), "--dry-run", "--out",
                     str(ctx.root / "inputs" / f"out_{tag}"), timeout=timeout)


def _info(ctx: Ctx, spec: str):
    return ctx.bench("info", f"volume:{images(ctx)}/{spec}")


# ------------------------------------------------------------------------------------------------ cause 7
NON_FINITE = ("inf", "-inf", "nan", "1e400")


def non_finite_cases() -> list[Case]:
    """inf, nan and 1e400 where an integer is expected: volume options, config keys, --set, CLI numbers."""
    out: list[Case] = []
    for bad in NON_FINITE:
        for option, image in (("pad", "mask.npz"), ("label", "labels.npz")):
            out.append(Case("7", f"info volume:{image}?{option}={bad}", lambda ctx, o=option, i=image, b=bad: one_line(
                _info(ctx, f"{i}?{o}={b}"), o)))
    for bad in ("nan", "inf"):
        out.append(Case("7", f"info volume:ct.npz?threshold={bad}", lambda ctx, b=bad: one_line(
            _info(ctx, f"ct.npz?threshold={b}"), "threshold")))
    for key in ("n", "seeds"):
        for bad in NON_FINITE:
            text = BASE_TOML.replace("n = [16]", f"n = [{bad}]" if key == "n" else f"n = [16]\nseeds = [{bad}]")
            out.append(Case("7", f"config grid.{key} = [{bad}]", lambda ctx, t=text, k=key, b=bad: one_line(
                dry(ctx, f"nf_{k}_{b}", t), k)))
    for bad in ("nan", "inf", "1e400"):
        out.append(Case("7", f"config metrics.n_samples = {bad}", lambda ctx, b=bad: one_line(
            dry(ctx, f"ns_{b}", BASE_TOML + f"[metrics]\nn_samples = {b}\n"), "n_samples")))
        out.append(Case("7", f"config params step_size = {bad}", lambda ctx, b=bad: one_line(
            dry(ctx, f"pp_{b}", BASE_TOML + f"params = {{ step_size = {b} }}\n"), "step_size")))
        out.append(Case("7", f"config sweep iterations = [10, {bad}]", lambda ctx, b=bad: one_line(
            dry(ctx, f"sw_{b}", BASE_TOML.replace("marching_cubes", "mc_taubin")
                + f"sweep = {{ iterations = [10, {b}] }}\n"), "iterations")))
    out.append(Case("7", "config noise snr = nan", lambda ctx: one_line(dry(
        ctx, "snr_nan", BASE_TOML.replace('{ kind = "none" }', '{ kind = "gaussian", snr = nan }')), "snr")))
    out.append(Case("7", "config run.memory_limit = nan", lambda ctx: one_line(
        dry(ctx, "mem_nan", BASE_TOML + "[run]\nmemory_limit = nan\n"), "memory_limit")))
    for bad in NON_FINITE:
        out.append(Case("7", f"reconstruct --set step_size={bad}", lambda ctx, b=bad: one_line(ctx.bench(
            "reconstruct", f"{images(ctx)}/sdf.npz", "-m", "marching_cubes", "--set", f"step_size={b}", "-o",
            "x.ply"), "step_size")))
        out.append(Case("7", f"run --method mc_taubin:iterations={bad}", lambda ctx, b=bad: one_line(ctx.bench(
            "run", "--phantoms", "sphere", "--n", "16", "--noise", "none", "--method", f"mc_taubin:iterations={b}",
            "--dry-run", "--out", "never"), "iterations")))
    for option in ("--n", "--seeds", "--n-samples", "--jobs"):
        for bad in ("inf", "nan"):
            out.append(Case("7", f"run {option} {bad}", lambda ctx, o=option, b=bad: one_line(ctx.bench(
                "run", "--quick", o, b, "--dry-run", "--out", "never"), o.lstrip("-").split("-")[0])))
    for args in (("volume", "sphere", "--n", "inf", "-o", "v.npz"), ("volume", "sphere", "--n", "16", "--seed",
                                                                     "nan", "--noise", "gaussian", "-o", "v.npz"),
                 ("check-method", "marching_cubes", "--n", "1e400")):
        out.append(Case("7", " ".join(args[:4]), lambda ctx, a=args: one_line(ctx.bench(*a))))
    return out


# ------------------------------------------------------------------------------------------------ cause 8
def nesting_cases() -> list[Case]:
    """Arrays and inline tables nested 1,000 to 100,000 levels: one line, no RecursionError."""
    out: list[Case] = []
    for depth in (1000, 3000, 5000, 100_000):
        out.append(Case("8", f"config: an array nested {depth} levels", lambda ctx, d=depth: one_line(dry(
            ctx, f"arr{d}", BASE_TOML + "[x]\na = " + "[" * d + "]" * d + "\n"), "deeply")))
    for depth in (3000, 20_000):
        out.append(Case("8", f"config: an inline table nested {depth} levels", lambda ctx, d=depth: one_line(dry(
            ctx, f"tab{d}", BASE_TOML + "[x]\na = " + "{b = " * d + "1" + "}" * d + "\n"), "deeply")))
    out.append(Case("8", "config: grid.phantoms nested 4000 levels", lambda ctx: one_line(dry(
        ctx, "ph4000", BASE_TOML.replace('["sphere"]', "[" * 4000 + '"sphere"' + "]" * 4000)))))
    out.append(Case("8", "config: a dotted key 5000 parts long", lambda ctx: one_line(dry(
        ctx, "dot5000", BASE_TOML + "[x]\n" + ".".join(["a"] * 5000) + " = 1\n"))))
    return out


# ------------------------------------------------------------------------------------------------ cause 10
def grid_size_cases() -> list[Case]:
    """Grids of 10^5 to 5 x 10^7 cells: refused in one line naming the count, within 30 s."""
    def big(ns: int, seeds: int, methods: int = 1) -> str:
        text = BASE_TOML.replace("n = [16]", f"n = {list(range(8, 8 + ns))}\nseeds = {list(range(seeds))}")
        extra = "".join(f'\n[[methods]]\nname = "marching_cubes"\nlabel = "mc{k}"\n' for k in range(methods - 1))
        return text + extra

    out = [Case("10", f"run --dry-run: {label} cells", lambda ctx, t=text, tag=tag: one_line(
        dry(ctx, tag, t, timeout=30), "cells"))
        for label, tag, text in (("5x10^7", "g5e7", big(1000, 1000, 50)), ("10^6", "g1e6", big(1000, 1000)),
                                 ("100,001", "g100001", big(1, 100_001)), ("2x10^5 by sweep", "gsweep",
                                  BASE_TOML.replace("marching_cubes", "mc_taubin") + "sweep = { iterations = "
                                  f"{list(range(1000))}, lamb = {[0.1 + k * 1e-4 for k in range(200)]} }}\n"))]
    out.append(Case("10", "run --quick --seeds 0..19999 on the command line", lambda ctx: one_line(ctx.bench(
        "run", "--quick", "--seeds", ",".join(map(str, range(20_000))), "--dry-run", "--out", "never",
        timeout=30), "cells")))
    out.append(Case("10", "run: 10^6 cells without --dry-run", lambda ctx: one_line(ctx.bench(
        "run", "--config", str(toml(ctx, "g1e6run", big(1000, 1000))), "--out", str(ctx.root / "g1e6run"),
        timeout=30), "cells")))
    return out


# ------------------------------------------------------------------------------------------------ cause 14
ARGPARSE = [
    ("run", "--memory-limit", "-1"), ("run", "--timeout", "-5"), ("run", "--method-timeout", "nan"),
    ("volume", "sphere", "--snr", "nan", "-o", "v.npz"), ("table", ".", "--format", "xml"),
    ("run", "--config", "x.toml", "--quick"), ("run", "--jobs", "0"), ("run", "--jobs", "abc"),
    ("run", "--bogus-option"), ("frobnicate",), ("info",), ("compare", "only_one"),
    ("reconstruct", "x.npz", "-o", "x.ply"), ("volume", "sphere", "--noise", "pink", "-o", "v.npz"),
    ("run", "--executor", "ray"), ("volume", "sphere", "--n", "0", "-o", "v.npz"), ("run", "--n", "-16"),
    ("perf", "--tolerance", "-1"), ("check-method",), ("run", "--score-timeout", "-inf"),
]


def argparse_cases() -> list[Case]:
    """Bad option values, unknown choices, exclusive options, missing arguments: one line, exit 2."""
    out = [Case("14", " ".join(a), lambda ctx, a=a: one_line(ctx.bench(*a))) for a in ARGPARSE]
    out.append(Case("14", "no command at all", lambda ctx: one_line(ctx.bench())))
    return out


# ------------------------------------------------------------------------------------------------ cause 16
def coerced_cases() -> list[Case]:
    """An option that cannot apply, a value of the wrong type, a key given twice: refused, not ignored."""
    info = {
        "pad=2 on a signed distance": ("sdf.npz?pad=2", "pad"),
        "pad given twice": ("mask.npz?pad=2&pad=3", "pad"),
        "an unknown option": ("mask.npz?padding=2", "padding"),
        "label=1.5": ("labels.npz?label=1.5", "label"),
        "mask=maybe": ("mask.npz?mask=maybe", "mask"),
        "invert=2": ("mask.npz?invert=2", "invert"),
        "resample=perhaps": ("mask.npz?resample=perhaps", "resample"),
        "threshold and label together": ("labels.npz?threshold=0.5&label=1", "label"),
        "threshold=abc": ("ct.npz?threshold=abc", "threshold"),
    }
    out = [Case("16", f"info: {name}", lambda ctx, s=spec, w=word: one_line(_info(ctx, s), w))
           for name, (spec, word) in info.items()]
    sets = {"--set step_size=1 --set step_size=2": ("--set", "step_size=1", "--set", "step_size=2"),
            "--set step_size=2.5": ("--set", "step_size=2.5"), "--set step_size=true": ("--set", "step_size=true"),
            "--set method=LEWINER": ("--set", "method=LEWINER")}
    for name, args in sets.items():
        out.append(Case("16", f"reconstruct {name}", lambda ctx, a=args: one_line(ctx.bench(
            "reconstruct", f"{images(ctx)}/sdf.npz", "-m", "marching_cubes", *a, "-o", "x.ply"), "step_size"
            if "step" in a[1] else "method")))
    out.append(Case("16", "run --method marching_cubes:step_size=1,step_size=2", lambda ctx: one_line(ctx.bench(
        "run", "--quick", "--method", "marching_cubes:step_size=1,step_size=2", "--dry-run", "--out", "never"),
        "step_size")))
    configs = {
        "threshold = true": (lambda d: BASE_TOML.replace('["sphere"]', f'[{{ volume = "{d}/ct.npz", threshold '
                                                                       '= true }]'), "threshold"),
        "n = [true]": (lambda d: BASE_TOML.replace("n = [16]", "n = [true]"), "n"),
        "n = ['16']": (lambda d: BASE_TOML.replace("n = [16]", 'n = ["16"]'), "n"),
        "seeds = [true]": (lambda d: BASE_TOML.replace("n = [16]", "n = [16]\nseeds = [true]"), "seeds"),
        "a misspelt grid key (phantom)": (lambda d: BASE_TOML.replace("phantoms =", "phantom ="), "phantom"),
        "a misspelt run key (timeot)": (lambda d: BASE_TOML + "[run]\ntimeot = 5\n", "timeot"),
        "params step_size = 2.5": (lambda d: BASE_TOML + "params = { step_size = 2.5 }\n", "step_size"),
        "a parameter in both params and sweep": (lambda d: BASE_TOML + "params = { step_size = 1 }\n"
                                                 "sweep = { step_size = [1, 2] }\n", "step_size"),
    }
    for name, (make, word) in configs.items():
        out.append(Case("16", f"config: {name}", lambda ctx, m=make, w=word, n=name: one_line(
            dry(ctx, "co_" + str(abs(hash(n)) % 10 ** 6), m(images(ctx))), w)))
    out.append(Case("16", "control: a good config dry-runs", lambda ctx: exits_ok(dry(ctx, "good", BASE_TOML))))
    return out


def cases() -> list[Case]:
    return non_finite_cases() + nesting_cases() + grid_size_cases() + argparse_cases() + coerced_cases()
