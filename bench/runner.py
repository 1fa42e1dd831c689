"""The grid runner behind ``python -m bench run``.

* :func:`expand_grid` turns a :class:`bench.config.RunConfig` into cells: plain dicts of parameters
  (phantom, variant, N, extent, noise kind, requested SNR, seed, method, label, parameters, ...), each with a
  stable ``cell_id``.
* :func:`run_cell` computes one cell from those parameters alone — it builds the volume, runs the method,
  measures its cost and evaluates the metrics — and returns a plain dict ``{"row": {...}, "artifacts":
  {...}}`` (the tidy result row; the mesh, per-vertex curvature, energy history and snapshots as arrays).
  It never raises for a failing method and never touches the output folder, so any executor can run it.
* :func:`run_grid` runs the cells in a pool of worker processes (``jobs``), one fresh process per cell
  (forked from a preloaded fork server), so a crash, a hang (``timeout``) or a leak stays in its cell.  Each
  finished cell is written at once as ``DIR/cells/<cell_id>.json`` (+ ``.npz`` artifacts), ``results.csv``
  is rewritten, and ``resume`` skips the cells already on disk.  At the end ``run.json`` and the HTML report
  (:mod:`bench.report`) are written.
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import importlib
import json
import math
import os
import platform
import re
import socket
import subprocess
import sys
import threading
import time
import traceback
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from phantoms import InputError, add_noise, get_phantom

__all__ = [
    "ID_COLUMNS", "TAIL_COLUMNS", "expand_grid", "cell_id", "run_cell", "run_grid", "RunSummary",
    "result_columns", "load_cells", "write_results_csv", "vertex_mean_curvature", "environment",
]

#: the leading columns of results.csv (then every metric, then the tail)
ID_COLUMNS = ["cell_id", "phantom", "variant", "N", "noise", "snr_requested", "snr_achieved", "seed",
              "method", "label", "parameters"]
#: columns the runner adds after the metrics
RUNNER_COLUMNS = ["iterations", "energy_final", "stop_reason", "wall_s", "peak_mem_mb"]
TAIL_COLUMNS = ["status", "error"]

CELLS_DIR = "cells"
MESHES_DIR = "meshes"
CACHE_DIR = "cache"


# ---------------------------------------------------------------------------------------------- grid
def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.=+-]+", "_", str(text)).strip("_") or "x"


def _canonical(obj: Any) -> str:
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=repr)


def cell_id(cell: dict) -> str:
    """A readable, stable identifier: ``<phantom>_<variant>_n<N>_<noise>[<snr>dB]_s<seed>_<label>_<hash>``.

    The hash covers every parameter of the cell, so sweeps and changed settings never collide.
    """
    key = {k: cell[k] for k in ("phantom", "variant", "n", "extent", "noise", "snr_requested", "seed",
                                "method", "params", "n_samples")}
    digest = hashlib.sha1(_canonical(key).encode()).hexdigest()[:8]
    noise = cell["noise"] if cell["noise"] == "none" else f"{cell['noise']}{cell['snr_requested']:g}dB"
    return "_".join([_slug(cell["phantom"]), cell["variant"], f"n{cell['n']}", _slug(noise),
                     f"s{cell['seed']}", _slug(cell["label"]), digest])


def expand_grid(cfg) -> list[dict]:
    """All cells of a config, in order phantom → variant → N → noise → seed → method.

    Clean cells (noise ``none``) are run for the first seed only: without noise the seed changes nothing
    but the metric sampling.
    """
    cells = []
    for phantom in cfg.phantoms:
        for variant in cfg.variants:
            for n in cfg.n:
                for noise in cfg.noise:
                    snr = noise.snr_for(phantom)
                    seeds = cfg.seeds[:1] if noise.kind == "none" else cfg.seeds
                    for seed in seeds:
                        for spec in cfg.methods:
                            for label, params in spec.instances():
                                cell = {
                                    "phantom": phantom, "variant": variant, "n": int(n),
                                    "extent": float(cfg.extent), "noise": noise.kind,
                                    "snr_requested": snr, "seed": int(seed), "method": spec.name,
                                    "label": label, "params": spec.params_for(params, phantom),
                                    "n_samples": int(cfg.n_samples), "imports": list(cfg.imports),
                                }
                                cell["cell_id"] = cell_id(cell)
                                cells.append(cell)
    ids = [c["cell_id"] for c in cells]
    if len(set(ids)) != len(ids):  # pragma: no cover - guarded by label uniqueness in validation
        raise InputError("the grid has duplicate cells (the same method settings listed twice)")
    return cells


# ---------------------------------------------------------------------------------------------- one cell
def _plain(value: Any) -> Any:
    """JSON-able plain Python values (numpy scalars/arrays, tuples, non-finite floats kept as floats)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        if value.size > 64:
            return f"<array shape {list(value.shape)}>"
        return _plain(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value)
    if value is None or isinstance(value, (int, str)):
        return value
    return repr(value)


def _import_plugins(modules) -> None:
    for mod in modules or ():
        importlib.import_module(mod)


def _volume_cache_path(cache_dir: str, cell: dict) -> Path:
    key = f"{cell['phantom']}_{cell['variant']}_n{cell['n']}_e{cell['extent']:g}"
    return Path(cache_dir) / f"{_slug(key)}.npz"


def build_volume(cell: dict, cache_dir: str | None = None):
    """The clean phantom volume of a cell (optionally cached on disk: the exact SDF of the ellipsoid costs
    seconds at N = 96 and is the same for every method and noise setting)."""
    from phantoms import Volume

    ph = get_phantom(cell["phantom"])
    path = _volume_cache_path(cache_dir, cell) if cache_dir else None
    if path is not None and path.exists():
        try:
            with np.load(path) as z:
                return ph, Volume(z["values"], z["origin"], z["spacing"])
        except Exception:  # a broken cache file is rebuilt
            pass
    vol = ph.volume(n=cell["n"], extent=cell["extent"], variant=cell["variant"])
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp.npz")
            np.savez(tmp, values=vol.values, origin=vol.origin, spacing=vol.spacing)
            os.replace(tmp, path)
        except OSError:
            pass
    return ph, vol


def vertex_mean_curvature(vertices, faces, h: float) -> np.ndarray:
    """Per-vertex mean curvature for pictures: paraboloid fit over every vertex within 2h (at least the
    1-ring), outward normals — the neighbourhood METRICS.md prescribes, so marching-cubes slivers do not
    blow it up."""
    from geometry import paraboloid_curvature, radius_neighbors, vertex_normals

    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    if len(v) == 0 or len(f) == 0:
        return np.zeros(len(v))
    nb = radius_neighbors(v, f, 2.0 * h)
    H, _ = paraboloid_curvature(v, vertex_normals(v, f), nb)
    return np.asarray(H, float)


def _snapshots(info: dict, faces: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """``{iteration: (vertices, faces)}`` from a method's info (vertices arrays or (vertices, faces) pairs)."""
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    snaps = info.get("snapshots") or {}
    if isinstance(snaps, dict):
        for it, s in snaps.items():
            try:
                it = int(it)
            except (TypeError, ValueError):
                continue
            if isinstance(s, (tuple, list)) and len(s) == 2:
                v, f = np.asarray(s[0], float), np.asarray(s[1], np.int64)
            else:
                v, f = np.asarray(s, float), faces
            if v.ndim == 2 and v.shape[1] == 3 and f.ndim == 2 and f.shape[1] == 3 and len(f) and f.max() < len(v):
                out[it] = (v, f)
    if 0 not in out:
        for key in ("initial_vertices", "init_vertices"):
            if key in info:
                v = np.asarray(info[key], float)
                if v.ndim == 2 and v.shape[1] == 3 and len(faces) and faces.max() < len(v):
                    out[0] = (v, faces)
                break
    return out


def _artifacts(rec, h: float) -> dict:
    """Arrays the report draws: the final mesh with its per-vertex H, the energy history and snapshots."""
    mesh = rec.mesh
    v = np.asarray(mesh.vertices, float)
    f = np.asarray(mesh.faces, np.int64)
    art: dict[str, np.ndarray] = {
        "vertices": v.astype(np.float32), "faces": f.astype(np.int32),
        "H": vertex_mean_curvature(v, f, h).astype(np.float32),
    }
    energy = rec.info.get("energy_history")
    if energy is not None and len(energy):
        art["energy_history"] = np.asarray(energy, float)
    snaps = _snapshots(rec.info, f)
    if snaps:
        its = sorted(snaps)
        art["snapshot_iterations"] = np.asarray(its, np.int64)
        for it in its:
            sv, sf = snaps[it]
            art[f"snap{it}_vertices"] = sv.astype(np.float32)
            if sf is not f:
                art[f"snap{it}_faces"] = sf.astype(np.int32)
            art[f"snap{it}_H"] = vertex_mean_curvature(sv, sf, h).astype(np.float32)
    return art


def _error_text(exc: BaseException) -> str:
    """``Type: first line of the message`` (the full traceback goes to the cell's JSON)."""
    lines = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {lines[0]}" if lines else type(exc).__name__


def run_cell(cell: dict, cache_dir: str | None = None) -> dict:
    """Compute one cell from its parameters; never raises for a failing method.

    Returns ``{"row": {...}, "artifacts": {...}, "traceback": str | None}``: ``row`` holds the ID columns,
    every metric, iterations/energy/cost, ``status`` (``ok`` / ``failed``) and ``error``; ``artifacts``
    holds numpy arrays (mesh, per-vertex H, energy history, snapshots) for the report.
    """
    t0 = time.perf_counter()
    row: dict[str, Any] = {
        "cell_id": cell["cell_id"], "phantom": cell["phantom"], "variant": cell["variant"], "N": cell["n"],
        "noise": cell["noise"], "snr_requested": cell["snr_requested"], "snr_achieved": None,
        "seed": cell["seed"], "method": cell["method"], "label": cell["label"],
        "parameters": _canonical(_plain(cell["params"])),
    }
    artifacts: dict = {}
    tb = None
    stage = "setup"
    try:
        _import_plugins(cell.get("imports"))
        stage = "volume"
        ph, vol = build_volume(cell, cache_dir)
        if cell["noise"] != "none":
            vol, achieved = add_noise(vol, cell["noise"], cell["snr_requested"], seed=cell["seed"])
            row["snr_achieved"] = float(achieved)
        stage = "method setup"
        from methods import get_method

        method = get_method(cell["method"], **cell["params"])
        row["parameters"] = _canonical(_plain(getattr(method, "config", cell["params"])))
        stage = "reconstruction"
        try:
            from bench.cost import measure
        except ImportError:  # pragma: no cover - bench.cost is part of the suite
            def measure(fn, *args):
                tm = time.perf_counter()
                out = fn(*args)
                return out, {"wall_s": time.perf_counter() - tm, "peak_mem_mb": None}
        rec, cost = measure(method.reconstruct, vol)
        info = dict(rec.info or {})
        energy = info.get("energy_history")
        runner_values = {
            "iterations": info.get("iterations"),
            "energy_final": (float(energy[-1]) if energy is not None and len(energy) else info.get("energy_final")),
            "stop_reason": info.get("stop_reason"),
            "wall_s": cost.get("wall_s"), "peak_mem_mb": cost.get("peak_mem_mb"),
        }
        stage = "pictures"
        try:
            artifacts = _artifacts(rec, vol.h)
        except Exception as exc:  # pictures are optional; the metrics are not
            artifacts = {}
            runner_values["artifact_error"] = _error_text(exc)
        stage = "metrics"
        from bench.metrics import evaluate

        metrics = evaluate(rec.mesh, ph, vol.h, n_samples=cell["n_samples"], seed=cell["seed"])
        row.update(_plain(dict(metrics)))
        for k, v in runner_values.items():
            if v is not None or k not in row:
                row[k] = _plain(v)
        row["status"] = "ok"
        row["error"] = ""
    except Exception as exc:
        row["status"] = "failed"
        row["error"] = f"{stage}: {_error_text(exc)}"
        tb = traceback.format_exc()
    row["cell_s"] = time.perf_counter() - t0
    return {"row": row, "artifacts": artifacts, "traceback": tb}


def failed_result(cell: dict, status: str, error: str) -> dict:
    """The result of a cell that produced nothing (crash, timeout)."""
    row = {
        "cell_id": cell["cell_id"], "phantom": cell["phantom"], "variant": cell["variant"], "N": cell["n"],
        "noise": cell["noise"], "snr_requested": cell["snr_requested"], "snr_achieved": None,
        "seed": cell["seed"], "method": cell["method"], "label": cell["label"],
        "parameters": _canonical(_plain(cell["params"])), "status": status, "error": error,
    }
    return {"row": row, "artifacts": {}, "traceback": None}


# ---------------------------------------------------------------------------------------------- worker processes
def _cell_process(cell: dict, cache_dir: str | None, result_conn, lifeline_conn) -> None:
    """Body of a worker process: run one cell, send the result, exit.  Exits at once if the runner dies."""

    def watch() -> None:
        try:
            lifeline_conn.recv()
        except (EOFError, OSError):
            pass
        os._exit(3)

    threading.Thread(target=watch, daemon=True).start()
    try:
        result = run_cell(cell, cache_dir)
    except KeyboardInterrupt:  # Ctrl-C reaches the whole process group: the runner handles it, not a row
        os._exit(130)
    except BaseException as exc:  # run_cell catches Exception; this is SystemExit etc.
        result = failed_result(cell, "failed", f"worker: {_error_text(exc)}")
    try:
        result_conn.send(result)
    except Exception as exc:  # e.g. an unpicklable artifact: send the row alone
        result["artifacts"] = {}
        result["row"]["artifact_error"] = f"could not send artifacts: {_error_text(exc)}"
        result_conn.send(result)
    result_conn.close()


@dataclass
class _Running:
    proc: Any
    conn: Any
    lifeline: Any
    cell: dict
    started: float
    deadline: float | None


_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")


class LocalExecutor:
    """Run cells in at most ``jobs`` worker processes at a time, each cell in its own process.

    Processes come from a fork server that preloaded the suite, so starting one costs milliseconds, and
    killing one (timeout) cannot take the others down.  ``submit``-style API kept tiny so another executor
    (e.g. Dask, issue 8) can replace it: ``run(cells, on_start, on_result)``.
    """

    def __init__(self, jobs: int, timeout: float | None, cache_dir: str | None = None,
                 preload: list[str] | None = None) -> None:
        self.jobs = max(1, int(jobs))
        self.timeout = timeout if timeout and timeout > 0 else None
        self.cache_dir = cache_dir
        self.preload = preload or []

    def _context(self):
        import multiprocessing as mp

        ctx = mp.get_context("forkserver")
        mods = ["bench.runner", "bench.metrics", "bench.cost", "methods", "geometry", "trimesh",
                "scipy.spatial", "skimage.measure"] + [f"methods.{m}" for m in
                                                       ("marching_cubes", "mc_taubin", "distmesh", "poisson",
                                                        "shape_gradient")] + list(self.preload)
        ctx.set_forkserver_preload(mods)
        # one BLAS/OpenMP thread per worker when several run at once (the fork server inherits this env)
        if self.jobs > 1:
            for var in _THREAD_VARS:
                os.environ.setdefault(var, "1")
        return ctx

    def _start(self, ctx, cell: dict) -> _Running:
        recv_end, send_end = ctx.Pipe(duplex=False)
        life_recv, life_send = ctx.Pipe(duplex=False)
        proc = ctx.Process(target=_cell_process, args=(cell, self.cache_dir, send_end, life_recv),
                           name=f"cell-{cell['cell_id']}", daemon=True)
        proc.start()
        send_end.close()
        life_recv.close()
        now = time.monotonic()
        return _Running(proc, recv_end, life_send, cell, now, now + self.timeout if self.timeout else None)

    @staticmethod
    def _finish(r: _Running) -> None:
        for c in (r.conn, r.lifeline):
            try:
                c.close()
            except OSError:
                pass
        r.proc.join(timeout=5)
        if r.proc.is_alive():  # pragma: no cover
            r.proc.kill()
            r.proc.join(timeout=5)

    def run(self, cells: list[dict], on_start: Callable[[dict], None],
            on_result: Callable[[dict, dict], None]) -> None:
        from multiprocessing.connection import wait

        ctx = self._context()
        pending = deque(cells)
        running: list[_Running] = []
        try:
            while pending or running:
                while pending and len(running) < self.jobs:
                    cell = pending.popleft()
                    on_start(cell)
                    running.append(self._start(ctx, cell))
                deadlines = [r.deadline for r in running if r.deadline is not None]
                wait_s = max(0.0, min(deadlines) - time.monotonic()) if deadlines else None
                wait([r.conn for r in running] + [r.proc.sentinel for r in running], timeout=wait_s)
                still = []
                for r in running:
                    result = None
                    if r.conn.poll():
                        try:
                            result = r.conn.recv()
                        except (EOFError, OSError):
                            result = self._crash(r)
                    elif not r.proc.is_alive():
                        result = self._crash(r)
                    elif r.deadline is not None and time.monotonic() >= r.deadline:
                        r.proc.kill()
                        result = failed_result(r.cell, "timeout",
                                               f"timeout: no result after {self.timeout:g} s (cell killed)")
                    if result is None:
                        still.append(r)
                        continue
                    self._finish(r)
                    result["row"].setdefault("cell_s", time.monotonic() - r.started)
                    on_result(r.cell, result)
                running = still
        finally:
            for r in running:  # interrupted: stop what is still running
                r.proc.kill()
                self._finish(r)

    def _crash(self, r: _Running) -> dict:
        r.proc.join(timeout=5)
        code = r.proc.exitcode
        if code is not None and code < 0:
            import signal

            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = str(-code)
            why = f"worker process killed by {name}" + (" (out of memory?)" if name == "SIGKILL" else "")
        else:
            why = f"worker process exited with code {code} without a result"
        return failed_result(r.cell, "failed", f"crash: {why}")


# ---------------------------------------------------------------------------------------------- storage
def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _json_default(o):
    return _plain(o)


def save_cell(out: Path, cell: dict, result: dict, save_meshes: bool = False) -> None:
    """Write one finished cell: artifacts (``.npz``) first, then the row (``.json``, which marks it done)."""
    cells_dir = out / CELLS_DIR
    cells_dir.mkdir(parents=True, exist_ok=True)
    cid = cell["cell_id"]
    art = result.get("artifacts") or {}
    if art:
        tmp = cells_dir / f".{cid}.{os.getpid()}.tmp.npz"
        np.savez_compressed(tmp, **art)
        os.replace(tmp, cells_dir / f"{cid}.npz")
        if save_meshes and "vertices" in art:
            import trimesh

            (out / MESHES_DIR).mkdir(exist_ok=True)
            mesh = trimesh.Trimesh(np.asarray(art["vertices"], float), np.asarray(art["faces"]), process=False)
            _write_atomic(out / MESHES_DIR / f"{cid}.ply", mesh.export(file_type="ply"))
    record = {"row": result["row"], "cell": cell, "traceback": result.get("traceback"),
              "finished": _dt.datetime.now().astimezone().isoformat(timespec="seconds")}
    _write_atomic(cells_dir / f"{cid}.json",
                  json.dumps(record, indent=1, default=_json_default, allow_nan=True).encode())


def load_cells(out: Path) -> dict[str, dict]:
    """``{cell_id: record}`` of every finished cell in ``out/cells`` (unreadable files are skipped)."""
    records = {}
    cells_dir = Path(out) / CELLS_DIR
    if not cells_dir.is_dir():
        return records
    for p in sorted(cells_dir.glob("*.json")):
        if p.name.startswith("."):
            continue
        try:
            rec = json.loads(p.read_text())
            records[rec["row"]["cell_id"]] = rec
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return records


def result_columns(rows: list[dict]) -> list[str]:
    """ID columns, every METRICS.md metric (in METRIC_NAMES order, then any further keys evaluate gave,
    e.g. the ``*_h`` distances), the runner's columns, then status and error."""
    try:
        from bench.metrics import METRIC_NAMES
        metric_names = list(METRIC_NAMES)
    except ImportError:  # pragma: no cover - the metrics are part of the suite
        metric_names = []
    tail = set(TAIL_COLUMNS) | set(ID_COLUMNS)
    cols = list(ID_COLUMNS)
    for name in metric_names:
        if name not in tail and name not in cols:
            cols.append(name)
    extra = []
    for r in rows:
        for k in r:
            if k not in cols and k not in tail and k not in extra and k not in ("cell_s", "artifact_error"):
                extra.append(k)
    cols += [k for k in extra if k not in RUNNER_COLUMNS]
    cols += [k for k in RUNNER_COLUMNS if k not in cols]
    return cols + TAIL_COLUMNS


def _csv_value(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else str(v)
    return v


def write_results_csv(out: Path, cells: list[dict], records: dict[str, dict]) -> Path:
    """``results.csv``: one row per finished cell of the grid, in grid order."""
    rows = [records[c["cell_id"]]["row"] for c in cells if c["cell_id"] in records]
    cols = result_columns(rows)
    path = Path(out) / "results.csv"
    tmp = path.with_name(f".results.{os.getpid()}.tmp.csv")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for r in rows:
            w.writerow([_csv_value(r.get(c)) for c in cols])
    os.replace(tmp, path)
    return path


# ---------------------------------------------------------------------------------------------- metadata
def _git_commit() -> dict | None:
    root = Path(__file__).resolve().parent.parent
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=10)
        if commit.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10)
        return {"commit": commit.stdout.strip(), "dirty": bool(dirty.stdout.strip())}
    except (OSError, subprocess.SubprocessError):
        return None


def _dependency_versions() -> dict[str, str | None]:
    from importlib import metadata

    names = ["levelset-bench"]
    try:
        for req in metadata.requires("levelset-bench") or []:
            m = re.match(r"^\s*([A-Za-z0-9_.\-]+)", req)
            if m and m.group(1) not in names:
                names.append(m.group(1))
    except metadata.PackageNotFoundError:
        names += ["numpy", "scipy", "scikit-image", "trimesh", "pandas", "matplotlib", "jinja2", "tqdm"]
    out = {}
    for n in names:
        try:
            out[n] = metadata.version(n)
        except metadata.PackageNotFoundError:
            out[n] = None
    return out


def _memory_gb() -> float | None:
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemTotal:"):
                    return round(int(line.split()[1]) / 1024 ** 2, 2)
    except OSError:
        pass
    return None


def environment() -> dict:
    """Python, dependency versions, git commit and machine facts for run.json."""
    return {
        "python": sys.version.split()[0],
        "python_implementation": platform.python_implementation(),
        "dependencies": _dependency_versions(),
        "git": _git_commit(),
        "machine": {
            "hostname": socket.gethostname(), "platform": platform.platform(), "machine": platform.machine(),
            "processor": platform.processor() or None, "cpu_count": os.cpu_count(), "memory_gb": _memory_gb(),
        },
    }


# ---------------------------------------------------------------------------------------------- the run
@dataclass
class RunSummary:
    out: Path
    total: int
    ok: int = 0
    failed: int = 0
    timeout: int = 0
    skipped: int = 0
    ran: int = 0
    seconds: float = 0.0
    report: Path | None = None
    report_error: str | None = None
    statuses: dict = field(default_factory=dict)

    def line(self) -> str:
        parts = [f"{self.ok} ok", f"{self.failed} failed", f"{self.timeout} timeout"]
        resumed = f", {self.skipped} already done" if self.skipped else ""
        where = f" → {self.report}" if self.report else f" → {self.out}"
        return (f"{self.total} cells: {', '.join(parts)} ({self.ran} run{resumed}) in "
                f"{self.seconds:.1f} s{where}")


def check_output_dir(out: Path, resume: bool) -> None:
    """Create ``out`` and make sure it is writable; refuse to mix a new run into an old one."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / f".write-test-{os.getpid()}"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise InputError(f"output folder {str(out)!r} is not writable: {exc.strerror or exc}") from None
    if not resume and any((out / CELLS_DIR).glob("*.json")):
        raise InputError(f"output folder {str(out)!r} already holds a run; use --resume to complete it or "
                         "choose another --out")


def run_grid(cfg, out: str | Path, *, jobs: int | None = None, resume: bool = False, retry_failed: bool = False,
             timeout: float | None = None, save_meshes: bool = False, progress: bool | None = None,
             report: bool = True, argv: list[str] | None = None, executor=None) -> RunSummary:
    """Run every cell of ``cfg`` (validated) into ``out``; returns the summary.  See the module docstring."""
    out = Path(out)
    check_output_dir(out, resume)
    cells = expand_grid(cfg)
    timeout = cfg.timeout if timeout is None else (timeout or None)
    jobs = jobs or os.cpu_count() or 1
    started = time.time()
    start_iso = _dt.datetime.now().astimezone().isoformat(timespec="seconds")
    _write_atomic(out / "config.json", json.dumps(cfg.to_dict(), indent=1).encode())

    records = load_cells(out) if resume else {}
    ids = {c["cell_id"] for c in cells}
    records = {k: v for k, v in records.items() if k in ids}
    if retry_failed:
        records = {k: v for k, v in records.items() if v["row"].get("status") == "ok"}
    todo = [c for c in cells if c["cell_id"] not in records]
    summary = RunSummary(out=out, total=len(cells), skipped=len(cells) - len(todo))

    run_meta_path = out / "run.json"
    previous = {}
    if resume and run_meta_path.exists():
        try:
            previous = json.loads(run_meta_path.read_text())
        except (OSError, ValueError):
            previous = {}
    session = {"start": start_iso, "argv": argv if argv is not None else sys.argv[1:], "jobs": jobs,
               "timeout_s": timeout, "cells_to_run": len(todo), "resumed_from": len(cells) - len(todo),
               "executor": (executor.describe() if hasattr(executor, "describe") else {"executor": "local"})}

    def write_meta(end: bool) -> None:
        sessions = list(previous.get("sessions", []))
        s = dict(session)
        if end:
            s["end"] = _dt.datetime.now().astimezone().isoformat(timespec="seconds")
            s["total_s"] = round(time.time() - started, 3)
            s["cells_run"] = summary.ran
        sessions.append(s)
        rows = [r["row"] for r in records.values()]
        cell_s = [float(r.get("cell_s") or 0.0) for r in rows]
        by_method: dict[str, list[float]] = {}
        for r in rows:
            if r.get("wall_s") is not None:
                by_method.setdefault(r.get("label", "?"), []).append(float(r["wall_s"]))
        meta = {
            "suite": "levelset-bench",
            "config": cfg.to_dict(),
            "config_source": cfg.source,
            "cells": {"total": len(cells), "finished": len(records),
                      "status": {k: sum(1 for r in rows if r.get("status") == k)
                                 for k in ("ok", "failed", "timeout")}},
            "start": previous.get("start", start_iso),
            "end": s.get("end"),
            "total_s": round(sum(x.get("total_s", 0.0) for x in sessions), 3),
            "timings": {"cells_s_sum": round(sum(cell_s), 3),
                        "method_wall_s_mean": {k: round(float(np.mean(v)), 4) for k, v in by_method.items()}},
            "sessions": sessions,
            **environment(),
        }
        _write_atomic(run_meta_path, json.dumps(meta, indent=1, default=_json_default).encode())

    write_meta(end=False)
    show = sys.stderr.isatty() if progress is None else progress
    from tqdm import tqdm

    bar = tqdm(total=len(cells), initial=summary.skipped, unit="cell", disable=not show, dynamic_ncols=True,
               desc="cells", file=sys.stderr)
    active: dict[str, str] = {}

    def on_start(cell: dict) -> None:
        active[cell["cell_id"]] = cell["label"]
        bar.set_postfix_str(f"{cell['phantom']}/{cell['noise']}/{cell['label']}", refresh=True)

    def on_result(cell: dict, result: dict) -> None:
        save_cell(out, cell, result, save_meshes)
        records[cell["cell_id"]] = {"row": result["row"], "cell": cell}
        write_results_csv(out, cells, records)
        active.pop(cell["cell_id"], None)
        summary.ran += 1
        status = result["row"].get("status")
        if status != "ok" and show:
            bar.write(f"{status}: {cell['cell_id']}: {result['row'].get('error', '')}")
        bar.update(1)

    if executor is None:
        executor = LocalExecutor(jobs, timeout, cache_dir=str(out / CACHE_DIR), preload=list(cfg.imports))
    try:
        executor.run(todo, on_start, on_result)
    finally:
        bar.close()
        write_results_csv(out, cells, records)
        for r in records.values():
            st = r["row"].get("status")
            if st in ("ok", "failed", "timeout"):
                setattr(summary, st, getattr(summary, st) + 1)
        summary.seconds = time.time() - started
        write_meta(end=True)
    if len(records) == len(cells):  # complete: the volume cache is only needed to resume
        import shutil

        shutil.rmtree(out / CACHE_DIR, ignore_errors=True)
    if report:
        try:
            from bench.report import write_report

            summary.report = write_report(out)
        except Exception as exc:  # the results are on disk; a broken report must not hide them
            summary.report_error = _error_text(exc)
            (out / "report_error.txt").write_text(traceback.format_exc())
    return summary
