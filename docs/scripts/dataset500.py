"""A ≥ 500-cell dataset run on the local executor and on Dask: the two results.csv must be identical.

Issue 31 asks that a dataset (a glob of volume files, README "Your data") of some hundreds of cells gives the same
rows on ``--executor dask`` as on the local process pool, and what each executor costs per cell. This script makes
the dataset (no download: seeded synthetic NIfTI masks of one or two ellipsoids, 24-32 voxels a side), writes a
grid config over its glob, runs it with ``--jobs W`` and with ``--executor dask --workers W``, compares the two
results.csv column by column except the columns that measure the machine (``wall_s``, ``peak_mem_mb``, any
``*_s``), and prints the cells, both wall times and the overhead per cell::

    PYTHONPATH=. python docs/scripts/dataset500.py            # 63 files x 2 noise x 4 methods = 504 cells
    PYTHONPATH=. python docs/scripts/dataset500.py --files 8  # 64 cells (the heavy test's size)

Overhead per cell = (wall × workers − Σ cell_s) / cells, where ``cell_s`` is a cell's own time (volume, method,
scoring) from its ``cells/*.json``: what the executor adds (process start, imports, scheduling, storing).
Exit 0 when the results are identical, 1 when they differ, 2 on bad input or a run that failed.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# columns of results.csv that measure the machine, not the result
COST_COLUMNS = {"wall_s", "peak_mem_mb"}
# the cheap methods: 4 rows per volume and noise setting (marching cubes swept over its two variants)
METHODS = """
[[methods]]
name = "marching_cubes"
sweep = { method = ["lewiner", "lorensen"] }

[[methods]]
name = "mc_taubin"

[[methods]]
name = "flying_edges"
"""
ROWS_PER_FILE = 2 * 4   # noise settings x method rows


def make_dataset(folder: Path, files: int, seed: int = 0) -> list[Path]:
    """Write ``files`` synthetic NIfTI masks: one or two ellipsoids of varied radii and sizes, from a seeded rng.

    Parameters
    ----------
    folder : Path
        Where the ``blobNNN.nii.gz`` files go (created).
    files : int
        How many volumes (≥ 1).
    seed : int
        The rng seed: the same seed gives the same files.

    Returns
    -------
    list of Path
        The files written, in name order.
    """
    import nibabel as nib

    if files < 1:
        raise ValueError(f"--files must be at least 1, got {files}")
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    paths = []
    for i in range(files):
        n = int(rng.integers(24, 33))
        x = np.indices((n, n, n), dtype=float)
        mask = np.zeros((n, n, n), bool)
        for _ in range(int(rng.integers(1, 3))):   # one ellipsoid, or two that may overlap
            centre = n / 2 + rng.uniform(-0.12, 0.12, 3) * n
            radii = rng.uniform(0.14, 0.3, 3) * n
            mask |= (((x - centre[:, None, None, None]) / radii[:, None, None, None]) ** 2).sum(0) < 1
        path = folder / f"blob{i:03d}.nii.gz"
        nib.save(nib.Nifti1Image(mask.astype(np.uint8), np.eye(4)), str(path))
        paths.append(path)
    return paths


def write_config(path: Path, pattern: str, n_samples: int = 2000) -> Path:
    """Write the grid config over the dataset glob: clean and Gaussian SNR 30, the cheap methods.

    Parameters
    ----------
    path : Path
        The ``.toml`` file to write.
    pattern : str
        The glob of the volume files (one phantom per file).
    n_samples : int
        Surface samples per metric (small: the cells stay cheap).

    Returns
    -------
    Path
        ``path``.
    """
    path.write_text(f"""name = "dataset500"
description = "A synthetic dataset: every file x 2 noise settings x 4 cheap method rows."

[grid]
phantoms = [{{ volume = {json.dumps(pattern)}, pad = 2 }}]
seeds = [0]
noise = [{{ kind = "none" }}, {{ kind = "gaussian", snr = 30 }}]
{METHODS}
[metrics]
n_samples = {n_samples}

[run]
timeout = 300
""")
    return path


def run_bench(config: Path, out: Path, workers: int, executor: str) -> float:
    """Run ``python -m bench run`` on one executor; return its wall time in seconds.

    Parameters
    ----------
    config : Path
        The grid config.
    out : Path
        The run folder.
    workers : int
        ``--jobs`` (local) or ``--workers`` (dask).
    executor : {'local', 'dask'}
        Which executor.

    Returns
    -------
    float
        The wall time of the whole command (start-up and the cluster's start included).

    Raises
    ------
    RuntimeError
        When the run exits non-zero (its last stderr line).
    """
    cmd = [sys.executable, "-m", "bench", "run", "--config", str(config), "--out", str(out), "--no-report"]
    if executor == "dask":
        cmd += ["--executor", "dask", "--workers", str(workers)]
    else:   # no memory limit, as on the Dask workers (a crash row names the local limit in force)
        cmd += ["--jobs", str(workers), "--memory-limit", "0"]
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        last = (proc.stderr.strip().splitlines() or ["(no stderr)"])[-1]
        raise RuntimeError(f"the {executor} run exited {proc.returncode}: {last}")
    return wall


def read_rows(run: Path) -> list[dict]:
    """The rows of a run folder's results.csv, in file order."""
    with open(run / "results.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def cell_seconds(run: Path) -> float:
    """Σ ``cell_s`` over a run's ``cells/*.json``: the time the cells themselves took."""
    return sum(json.loads(p.read_text())["row"].get("cell_s") or 0.0 for p in (run / "cells").glob("*.json"))


def is_cost_column(name: str) -> bool:
    """True for a column that measures the machine (time, memory), not the result."""
    return name in COST_COLUMNS or name.endswith("_s")


def compare_results(ref: list[dict], got: list[dict]) -> list[str]:
    """The differences between two runs' rows, ignoring the cost columns; empty when identical.

    Parameters
    ----------
    ref, got : list of dict
        The rows of the two results.csv (:func:`read_rows`).

    Returns
    -------
    list of str
        One line per difference: columns, cells missing from one run, cell order, values.
    """
    diffs = []
    cols_ref, cols_got = list(ref[0]) if ref else [], list(got[0]) if got else []
    if cols_ref != cols_got:
        diffs.append(f"columns differ: {sorted(set(cols_ref) ^ set(cols_got)) or 'same set, other order'}")
    ids_ref, ids_got = [r["cell_id"] for r in ref], [r["cell_id"] for r in got]
    for cid in sorted(set(ids_ref) - set(ids_got)):
        diffs.append(f"{cid}: in the first run only")
    for cid in sorted(set(ids_got) - set(ids_ref)):
        diffs.append(f"{cid}: in the second run only")
    if len(set(ids_got)) != len(ids_got):
        diffs.append("the second run has a cell more than once")
    if ids_ref != ids_got and set(ids_ref) == set(ids_got):
        diffs.append("the cells are in another order")
    by_id = {r["cell_id"]: r for r in got}
    for r in ref:
        other = by_id.get(r["cell_id"])
        if other is None:
            continue
        for col, value in r.items():
            if not is_cost_column(col) and other.get(col) != value:
                diffs.append(f"{r['cell_id']}: {col} {value!r} != {other.get(col)!r}")
    return diffs


def compare_executors(base: Path, files: int, workers: int, seed: int = 0) -> dict:
    """Make the dataset under ``base``, run it on both executors, compare: the figures and the differences.

    Parameters
    ----------
    base : Path
        A folder for the dataset, the config and the two run folders ``local`` and ``dask``.
    files : int
        Volumes in the dataset (cells = 8 × files).
    workers : int
        Processes of each executor.
    seed : int
        The dataset's rng seed.

    Returns
    -------
    dict
        ``cells``, ``statuses``, ``wall_s`` and ``cell_s`` and ``overhead_per_cell_s`` per executor, ``diffs``.
    """
    if workers < 1:
        raise ValueError(f"--workers must be at least 1, got {workers}")
    make_dataset(base / "scans", files, seed)
    config = write_config(base / "dataset500.toml", str(base / "scans" / "*.nii.gz"))
    out = {"wall_s": {}, "cell_s": {}, "overhead_per_cell_s": {}}
    for executor in ("local", "dask"):
        run = base / executor
        wall = run_bench(config, run, workers, executor)
        rows = read_rows(run)
        busy = cell_seconds(run)
        out["wall_s"][executor], out["cell_s"][executor] = wall, busy
        out["overhead_per_cell_s"][executor] = (wall * workers - busy) / max(len(rows), 1)
    ref, got = read_rows(base / "local"), read_rows(base / "dask")
    out["cells"] = len(ref)
    out["statuses"] = {s: sum(r["status"] == s for r in ref) for s in sorted({r["status"] for r in ref})}
    out["diffs"] = compare_results(ref, got)
    return out


def _report(res: dict, workers: int) -> str:
    lines = [f"cells: {res['cells']} ({', '.join(f'{n} {s}' for s, n in res['statuses'].items())}), "
             f"{workers} workers each"]
    for ex in ("local", "dask"):
        lines.append(f"{ex:5s}: wall {res['wall_s'][ex]:.1f} s, Σ cell_s {res['cell_s'][ex]:.1f} s, "
                     f"overhead per cell {res['overhead_per_cell_s'][ex]:.2f} s")
    if res["diffs"]:
        lines.append(f"DIFFERENT: {len(res['diffs'])} differences (cost columns ignored):")
        lines += ["  " + d for d in res["diffs"][:50]]
    else:
        lines.append("identical: every row and column the same except the cost columns "
                     "(wall_s, peak_mem_mb, *_s)")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """The command line: make, run twice, compare, print; exit 0 identical, 1 different, 2 bad input.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The exit code.
    """
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--files", type=int, default=63, help="volumes in the dataset; cells = 8 x files (default 63: 504)")
    p.add_argument("--workers", type=int, default=2, help="--jobs of the local run, --workers of the Dask run")
    p.add_argument("--seed", type=int, default=0, help="the dataset's rng seed")
    p.add_argument("--keep", metavar="DIR", help="work in DIR (kept) instead of a temporary folder")
    args = p.parse_args(argv)
    try:
        if args.keep:
            base = Path(args.keep)
            if base.exists() and any(base.iterdir()):
                raise ValueError(f"--keep {base}: the folder exists and is not empty")
            res = compare_executors(base, args.files, args.workers, args.seed)
        else:
            with tempfile.TemporaryDirectory(prefix="dataset500-") as tmp:
                res = compare_executors(Path(tmp), args.files, args.workers, args.seed)
    except (ValueError, RuntimeError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(_report(res, args.workers))
    return 1 if res["diffs"] else 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONWARNINGS", "ignore")
    sys.exit(main())
