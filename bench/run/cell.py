"""One cell from its parameters alone: build the volume, run the method, measure it, score it.

:func:`run_cell` never raises for a failing method and never touches the run folder (only the shared volume
cache, when given), so any executor can run it anywhere.  It takes a :class:`~bench.run.contracts.Cell` (or its
dict form) and returns a :class:`~bench.run.contracts.CellResult` (``row``, ``artifacts``, ``traceback``).

``row`` (a :class:`~bench.run.row.ResultRow`, filled as a dict as the stages go and converted once at the end) is
the cell's results.csv row (ID columns, every metric, the method's iterations / energy / stop reason, cost,
``status`` ``ok`` / ``invalid`` (the mesh fails :func:`bench.metrics.validity.check_mesh`, or has zero area,
:func:`degenerate_reasons`: ``error`` says why; the metrics that can be computed are kept) / ``failed`` and
``error`` (over the process's memory limit: ``memory limit (N GB) exceeded in the method`` / ``in scoring ...``, see
:mod:`bench.run.limits`) / ``skipped`` (the method declines the input, :meth:`methods.Method.skip_reason`: ``error``
is its reason; no metrics)); ``artifacts`` holds the arrays the report draws: the final mesh with its per-vertex
mean curvature, the energy history and the snapshots.  Which ``Reconstruction.info`` keys are read is documented in
:data:`methods.INFO_KEYS`.  The method's :meth:`~methods.Method.warm_up` runs before ``reconstruct`` is timed
(``phase_s["warm_up"]``), so compiling does not count in ``wall_s``.
"""

from __future__ import annotations

import hashlib
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from geometry.files import WriteError
from methods import get_method, import_plugins
from methods.contract import MethodSkipped, as_reconstruction, check_skip, run_reconstruct, run_warm_up
from phantoms import Volume, add_noise, get_phantom
from phantoms.degrade import degrade

from ..metrics.flags import result_flags
from ..metrics.validity import check_mesh
from .contracts import Cell, CellResult, ResultRow
from .cost import measure
from .grid import as_cell, canonical_json, slug
from .limits import memory_error
from .store import save_npz
from .view import view_arrays
from .values import error_text, plain

__all__ = ["run_cell", "failed_result", "build_volume", "cell_source", "truth_samples", "vertex_mean_curvature",
           "method_info", "degenerate_reasons"]


def _volume_cache_path(cache_dir: str, cell: Cell) -> Path:
    source = cell_source(cell)
    name = cell.phantom if source == cell.phantom else f"{cell.phantom}_{hashlib.sha1(source.encode()).hexdigest()[:8]}"
    key = f"{name}_{cell.variant}_n{cell.n}_e{cell.extent:g}"
    return Path(cache_dir) / f"{slug(key)}.npz"


def cell_source(cell: Cell) -> str:
    """What resolves the cell's phantom (:func:`phantoms.get_phantom`): its ``source`` (a file of a dataset
    glob, named by its stem) or its name."""
    return cell.source or cell.phantom


def _file_stamp(path: str) -> np.ndarray:
    """``[mtime_ns, size]`` of a file (zeros when it cannot be read): a cached volume follows its file's version."""
    try:
        st = Path(path).expanduser().stat()
        return np.array([st.st_mtime_ns, st.st_size], np.int64)
    except OSError:
        return np.zeros(2, np.int64)


def _cached_mask_level_set(path: Path, stamp: np.ndarray):
    """The level set of a user's mask from the run's cache (its mask, bit-packed and compressed), rebuilt by the
    same function the image's reading uses — the same values to the bit; None without a usable cache file."""
    from phantoms.user import mask_level_set

    try:
        with np.load(path) as z:
            if not np.array_equal(z["stamp"], stamp):
                return None
            shape = tuple(int(x) for x in z["shape"])
            inside = np.unpackbits(z["mask"], count=int(np.prod(shape))).reshape(shape).astype(bool)
            return mask_level_set(inside, z["origin"], z["spacing"])
    except Exception:  # a missing or broken cache file is rebuilt
        return None


def _user_volume_phantom(source: str, cache_dir: str | None, cell: Cell):
    """A ``volume:`` phantom whose mask level set (a label, a threshold, a mask) is built once per run: the first
    cell stores the mask (one bit a voxel, compressed: a few KB for a label of a CT's grid, not the float64 φ and
    raw mask of 16 bytes a voxel) and the others rebuild the signed distance from it without reading the image."""
    from phantoms.user import VolumePhantom, parse_spec

    if not cache_dir:
        return get_phantom(source)
    path = _volume_cache_path(cache_dir, cell).with_name(
        f"{slug(cell.phantom)}_{hashlib.sha1(source.encode()).hexdigest()[:8]}_mask.npz")
    stamp = _file_stamp(parse_spec(source)[0])
    level_set = _cached_mask_level_set(path, stamp) if path.exists() else None
    if level_set is not None:
        return VolumePhantom(source, level_set=level_set)
    ph = get_phantom(source)
    ls = getattr(ph, "level_set", None)
    if ls is not None and ls.kind == "mask":
        inside = np.asarray(ls.raw) > 0.5
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            save_npz(path, {"mask": np.packbits(inside, axis=None), "shape": np.asarray(inside.shape, np.int64),
                            "origin": ls.origin, "spacing": ls.spacing, "stamp": stamp}, compressed=True)
        except (OSError, WriteError):  # the cache is an optimisation; a full disk must not fail the cell
            pass
    return ph


def build_volume(cell: Cell, cache_dir: str | None = None):
    """``(phantom, clean volume)`` of a cell, optionally cached on disk: the exact SDF of a phantom can cost
    seconds at N = 96 and is the same for every method and noise setting.  ``n`` 0 is a user volume's native
    grid.  A user's volume is cached as its mask (:func:`_user_volume_phantom`), never as its φ: the image is
    read once per run."""
    source = cell_source(cell)
    if source.startswith("volume:"):
        ph = _user_volume_phantom(source, cache_dir, cell)
        return ph, ph.volume(n=cell.n or None, extent=cell.extent, variant=cell.variant)
    ph = get_phantom(source)
    path = _volume_cache_path(cache_dir, cell) if cache_dir else None
    if path is not None and path.exists():
        try:
            with np.load(path) as z:
                kind = str(z["kind"]) if "kind" in z.files else "sdf"
                extra = {"raw": z["raw"], "level": float(z["level"])} if kind != "sdf" else {}
                return ph, Volume(z["values"], z["origin"], z["spacing"], kind=kind, **extra)
        except Exception:  # a broken cache file is rebuilt
            pass
    vol = ph.volume(n=cell.n or None, extent=cell.extent, variant=cell.variant)
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            kind = {} if vol.kind == "sdf" else {"kind": np.str_(vol.kind), "raw": vol.raw, "level": vol.level}
            save_npz(path, {"values": vol.values, "origin": vol.origin, "spacing": vol.spacing, **kind},
                     compressed=False)
        except (OSError, WriteError):  # the cache is an optimisation; a full disk must not fail the cell
            pass
    return ph, vol


def truth_samples(cell: Cell, ph, cache_dir: str | None = None) -> np.ndarray | None:
    """The phantom's area-uniform surface samples the metrics compare with (``ph.sample_surface(n_samples,
    seed)``), optionally cached on disk beside the volume: the same for every method and noise setting."""
    if ph is None:
        return None
    n, seed = int(cell.n_samples), int(cell.seed)
    path = (_volume_cache_path(cache_dir, cell).with_name(f"{slug(cell.phantom)}_samples{n}_s{seed}.npz")
            if cache_dir else None)
    if path is not None and path.exists():
        try:
            with np.load(path) as z:
                pts = z["points"]
            if pts.shape == (n, 3):
                return pts
        except Exception:  # a broken cache file is rebuilt
            pass
    try:
        pts = np.asarray(ph.sample_surface(n, seed)[0], float)
    except NotImplementedError:  # a phantom without a truth: the metrics say so themselves
        return None
    if path is not None:
        try:
            save_npz(path, {"points": pts}, compressed=False)
        except (OSError, WriteError):
            pass
    return pts


#: snapshots up to this many vertices get their per-vertex H in the cell (the paper's 1,896-vertex sphere: 25 ms
#: each); the report fits larger ones only for the pictures it draws
SNAPSHOT_H_MAX_VERTICES = 20_000


def vertex_mean_curvature(vertices, faces, h: float) -> np.ndarray:
    """Per-vertex mean curvature for pictures: paraboloid fit over every vertex within 2h (at least the
    1-ring), outward normals — the neighbourhood docs/METRICS.md prescribes, so marching-cubes slivers do not
    blow it up."""
    from geometry import radius_curvature

    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    if len(v) == 0 or len(f) == 0:
        return np.zeros(len(v))
    H, _ = radius_curvature(v, f, 2.0 * h)
    return np.asarray(H, float)


def _snapshot(s, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """One snapshot as ``(vertices, faces)``: a vertices array (the final mesh's faces) or a pair."""
    if isinstance(s, (tuple, list)) and len(s) == 2:
        v, f = np.asarray(s[0], float), np.asarray(s[1], np.int64)
    else:
        v, f = np.asarray(s, float), faces
    if v.ndim == 2 and v.shape[1] == 3 and f.ndim == 2 and f.shape[1] == 3 and len(f) and f.max() < len(v):
        return v, f
    return None


def _snapshots(info: dict, faces: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """``{iteration: (vertices, faces)}`` from a method's ``info["snapshots"]``."""
    out: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    snaps = info.get("snapshots") or {}
    if isinstance(snaps, dict):
        for it, s in snaps.items():
            try:
                it = int(it)
            except (TypeError, ValueError):
                continue
            snap = _snapshot(s, faces)
            if snap is not None:
                out[it] = snap
    return out


def _artifacts(rec, h: float, curvature: dict | None = None, sdf=None) -> dict:
    """Arrays the report draws: the final mesh with its per-vertex H (and K: ``curvature``, the metrics' own
    when they computed them for these vertices), the viewer's decimated mesh (coloured by H and, with the
    truth's signed distance function ``sdf``, the distance in h), the energy history and snapshots."""
    v = np.asarray(rec.mesh.vertices, float)
    f = np.asarray(rec.mesh.faces, np.int64)
    curvature = {k: c for k, c in (curvature or {}).items() if len(c) == len(v)}
    art: dict[str, np.ndarray] = {
        "vertices": v.astype(np.float32), "faces": f.astype(np.int32),
        "H": np.asarray(curvature["H"] if "H" in curvature else vertex_mean_curvature(v, f, h)).astype(np.float32),
    }
    if "K" in curvature:
        art["K"] = np.asarray(curvature["K"]).astype(np.float32)
    colours = {"H": art["H"]}
    if sdf is not None and len(v):
        try:
            colours["d"] = np.asarray(sdf(v), float) / h
        except Exception:  # noqa: BLE001 — the viewer's distance map is optional
            pass
    art.update(view_arrays(v, f, colours))
    art["spacing"] = np.float64(h)   # the report fits the large snapshots' H for the pictures it draws
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
            if len(sv) <= SNAPSHOT_H_MAX_VERTICES:   # cheap here, in parallel; the report fits the others
                art[f"snap{it}_H"] = vertex_mean_curvature(sv, sf, h).astype(np.float32)
    return art


def degenerate_reasons(mesh) -> list[str]:
    """Why a mesh the validity check passed still cannot be scored: a closed mesh of zero area (every vertex of a
    face in one point or on one line — a tiny label meshed to nothing) has no surface to sample; [] otherwise."""
    v = np.asarray(mesh.vertices, float)
    f = np.asarray(mesh.faces, np.int64)
    if len(f) == 0 or len(v) == 0:
        return ["empty mesh: no faces"]
    area = float(np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()) / 2
    if not area > 0:
        return [f"empty mesh: zero area ({len(f):,} faces, every one degenerate)"]
    return []


def _stopwatch(phases: dict):
    """``lap(name)``: add the seconds since the previous lap to ``phases[name]``."""
    last = [time.perf_counter()]

    def lap(name: str) -> None:
        now = time.perf_counter()
        phases[name] = phases.get(name, 0.0) + now - last[0]
        last[0] = now

    return lap


def _id_row(cell: Cell) -> dict[str, Any]:
    """The identifying columns of a cell's row."""
    return {
        "cell_id": cell.cell_id, "phantom": cell.phantom, "variant": cell.variant, "N": cell.n,
        "noise": cell.noise, "snr_requested": cell.snr_requested, "snr_achieved": None,
        "seed": cell.seed, "method": cell.method, "label": cell.label,
        "parameters": canonical_json(plain(cell.params)),
        "degrade": cell.degrade or "none", "input_kind": "sdf",
        **({"source": cell.source} if cell.source else {}),
    }


def _runner_values(rec, cost: dict) -> dict[str, Any]:
    """The columns taken from the method's own info (see :data:`methods.INFO_KEYS`) and the cost."""
    info = rec.info or {}
    energy = info.get("energy_history")
    return {
        "iterations": info.get("iterations"),
        "energy_final": (float(energy[-1]) if energy is not None and len(energy) else info.get("energy_final")),
        "stop_reason": info.get("stop_reason"),
        "wall_s": cost.get("wall_s"), "peak_mem_mb": cost.get("peak_mem_mb"),
    }


def method_info(info: dict) -> dict:
    """The method's ``info`` as plain values for the cell's json (``row["method_info"]``): every key, the
    author's own ones included; the arrays the artifacts hold (energy history, snapshots) left out."""
    return {str(k): plain(v) for k, v in (info or {}).items() if k not in ("snapshots", "energy_history")}


def _input_volume(cell: Cell, cache_dir: str | None, row: dict, lap):
    """``(truth, clean volume, the volume the method gets)``: the phantom's volume, degraded and noised as the
    cell says; the row gets N, h, whether there is a truth, the phantom's shape kind, the input kind and the
    achieved SNR."""
    ph, vol = build_volume(cell, cache_dir)
    if not cell.n:
        row["N"] = int(max(vol.shape))           # a user volume on its native grid
    truth = ph.ground_truth()
    row["h"], row["has_truth"], row["input_kind"] = float(vol.h), truth is not None, vol.kind
    row["shape_kind"] = getattr(ph, "shape_kind", None)      # (a phantom that declares none: None)
    clean = vol
    lap("volume")
    if cell.degrade:
        vol = degrade(ph, cell.degrade, cell.n, cell.extent, seed=cell.seed, clean=vol)
        row["input_kind"], row["h"] = vol.kind, float(vol.h)
        lap("degrade")
    if cell.noise != "none":
        vol, achieved = add_noise(vol, cell.noise, cell.snr_requested, seed=cell.seed)
        row["snr_achieved"] = float(achieved)
        lap("noise")
    return truth, clean, vol


def _read_as_distance(clean, vol, row: dict):
    """The clean and the given volume as the validity check and the fidelity metrics read them: φ / |∇φ| when φ
    is not a distance (:func:`bench.metrics.fidelity.as_distance`); the row gets the median |∇φ| found.  Third,
    the grid the SDF energy reads as S: the clean one as built (an exact distance, or a mask's: a thin part's
    small |∇φ| must not rescale it — the cortex's is 0.7 at N = 41), an intensity's read as a distance."""
    from bench.metrics.fidelity import as_distance

    scored, g = as_distance(vol)
    row["phi_gradient"] = g
    clean_read = scored if clean is vol else as_distance(clean)[0]
    return clean_read, scored, (clean if clean.kind != "intensity" else clean_read)


def _method(cell: Cell, vol, row: dict):
    """The cell's method, its parameters in the row, after it said it takes ``vol``
    (:func:`methods.contract.check_skip`: :class:`methods.MethodSkipped` when it does not)."""
    method = get_method(cell.method, **cell.params)
    row["parameters"] = canonical_json(plain(getattr(method, "config", cell.params)))
    check_skip(method, vol)
    return method


def _ended(exc: Exception, stage: str) -> tuple[str, str, str | None]:
    """``(status, error, traceback)`` of a cell that ended in ``exc`` at ``stage``: ``skipped`` with the method's
    reason (no traceback: nothing went wrong), else ``failed`` — over the process's memory limit
    (:mod:`bench.run.limits`) saying so and in which phase."""
    if isinstance(exc, MethodSkipped):
        return "skipped", exc.reason, None
    return "failed", memory_error(exc, stage) or f"{stage}: {error_text(exc)}", traceback.format_exc()


def _metrics(rec, truth, vol, energy_grid, invalid: list, cell: Cell, cache_dir: str | None,
             artifacts: dict) -> tuple[dict, dict, dict]:
    """``(metrics, per-vertex mean curvature, metric phase times)`` of the method's mesh (the metrics with the
    ``topology_vs_data_detail`` column, :func:`bench.metrics.evaluate`'s ``details``).  An invalid mesh keeps
    what can be computed (no metrics when they fail); a valid one whose metrics fail, or any that runs out of
    memory, fails the cell — its pictures go into ``artifacts`` first, they are still worth keeping."""
    from bench.metrics import evaluate

    final_H: dict = {}
    metric_phases: dict = {}
    details: dict = {}
    try:
        metrics = evaluate(rec.mesh, truth, vol.h, volume=vol, n_samples=cell.n_samples, seed=cell.seed,
                           timings=metric_phases, vertex_H=final_H,
                           truth_points=truth_samples(cell, truth, cache_dir), clean=energy_grid, details=details)
    except Exception as exc:
        if not invalid or memory_error(exc, "metrics"):
            try:
                artifacts.update(_artifacts(rec, vol.h, None, getattr(truth, "sdf", None)))
            except Exception:  # noqa: BLE001
                pass
            raise
        metrics = {}
    if "topology_vs_data" in details:
        metrics = {**metrics, "topology_vs_data_detail": details["topology_vs_data"]}
    return metrics, final_H, metric_phases


def _pictures(rec, vol, final_H: dict, truth, runner_values: dict) -> dict:
    """The cell's artifacts (pictures, arrays); optional — a failure is recorded in ``runner_values``'s
    ``artifact_error`` and the cell goes on."""
    try:
        return _artifacts(rec, vol.h, final_H, getattr(truth, "sdf", None))
    except Exception as exc:  # pictures are optional; the metrics are not
        runner_values["artifact_error"] = error_text(exc)
        return {}


def _finish(row: dict, runner_values: dict, truth, invalid: list) -> None:
    """The runner's columns, the flags, the status and the error of a cell whose method returned a mesh."""
    for k, v in runner_values.items():
        if v is not None or k not in row:
            row[k] = plain(v)
    row["flags"] = ";".join(result_flags(row, truth))
    row["status"] = "invalid" if invalid else "ok"
    row["error"] = f"invalid: {'; '.join(invalid)}" if invalid else ""


def run_cell(cell: Cell | dict, cache_dir: str | None = None, on_phase=None) -> CellResult:
    """Compute one cell from its parameters; never raises for a failing method (see the module docstring).

    Parameters
    ----------
    cell : Cell or dict
        A cell of :func:`bench.run.grid.expand_grid`, or its dict form (:meth:`Cell.from_dict`).
    cache_dir : str, optional
        Folder of the shared cache of clean volumes and truth samples (the same for every method and noise).
    on_phase : callable, optional
        ``on_phase(phase, facts)``, called as the method starts (``"method"``, {}) and as it returns
        (``"scoring"``, its wall time and info columns): the executor's per-phase time limits.

    Returns
    -------
    CellResult
        Its row, artifacts and traceback; a failing method's row has ``status`` ``failed``, ``error``; a method
        that declines the input (:meth:`methods.Method.skip_reason`) ``skipped`` and its reason.
    """
    cell = as_cell(cell)
    t0, c0 = time.perf_counter(), time.process_time()
    row = _id_row(cell)
    artifacts: dict = {}
    tb = None
    stage = "setup"
    phases = row["phase_s"] = {}
    lap = _stopwatch(phases)
    try:
        import_plugins(cell.imports)
        stage = "volume"
        truth, clean, vol = _input_volume(cell, cache_dir, row, lap)
        stage = "method setup"
        method = _method(cell, vol, row)            # MethodSkipped: a skipped row
        lap("setup")
        stage = "warm-up"
        run_warm_up(method)                         # not timed: compiling is not the method's wall_s
        lap("warm_up")
        stage = "reconstruction"
        if on_phase is not None:
            on_phase("method", {})
        rec, cost = measure(run_reconstruct, method, vol)   # sys.exit() in the method: a failed row
        rec = as_reconstruction(rec, cell.method)   # a bare trimesh etc.: named, not an AttributeError
        runner_values = _runner_values(rec, cost)
        row["method_info"] = method_info(rec.info)
        if on_phase is not None:
            on_phase("scoring", plain(runner_values))
        lap("method")
        stage = "validity"
        # against the clean level set the grid knows (and, with noise, the one the method was given)
        clean, vol, energy_grid = _read_as_distance(clean, vol, row)
        invalid = check_mesh(rec.mesh, clean, given=None if vol is clean else vol) or degenerate_reasons(rec.mesh)
        lap("validity")
        stage = "metrics"
        metrics, final_H, metric_phases = _metrics(rec, truth, vol, energy_grid, invalid, cell, cache_dir,
                                                   artifacts)
        row.update(plain(dict(metrics)))
        lap("metrics")
        phases.update({f"metrics/{k}": v for k, v in metric_phases.items()})
        stage = "pictures"
        artifacts = _pictures(rec, vol, final_H, truth, runner_values)
        lap("artifacts")
        _finish(row, runner_values, truth, invalid)
    except Exception as exc:
        row["status"], row["error"], tb = _ended(exc, stage)
    row["cell_s"] = time.perf_counter() - t0
    row["cpu_s"] = time.process_time() - c0        # all threads of the cell: its cost whatever the machine's load
    return CellResult(ResultRow.from_dict(row, strict=True), artifacts, tb)


def failed_result(cell: Cell | dict, status: str, error: str) -> CellResult:
    """The result of a cell that produced nothing (a crash, a timeout), shaped as :func:`run_cell`'s.

    Parameters
    ----------
    cell : Cell or dict
        The cell (or its dict form).
    status : str
        The row's ``status``, e.g. ``failed``.
    error : str
        What happened, one line (the row's ``error``).

    Returns
    -------
    CellResult
        Its row holds the ID columns, status and error; no artifacts, no traceback.
    """
    return CellResult(ResultRow.from_dict({**_id_row(as_cell(cell)), "status": status, "error": error}, strict=True))
