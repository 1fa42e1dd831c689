"""``python -m bench check-method NAME``: does a method honour the contract of :class:`methods.Method`?

The counterpart of ``benchopt test`` for a method author.  The method runs on a few small volumes (N ≈ 24–32,
seconds in all): the exact signed distances of the suite's phantoms (:func:`phantoms.get_phantom`), sampled on
the cases' grids:

* ``sphere``      — the unit sphere centred in a cubic grid;
* ``anisotropic`` — an ellipsoid (1.0, 0.7, 0.5) off the grid centre, on a grid with a different spacing and
  number of points per axis and a non-zero origin (catches index coordinates, transposed axes, a
  spacing taken as one number);
* ``noisy``       — the sphere with Gaussian noise at 30 dB (checked against the clean level set);
* ``torus``       — a torus (R = 1, r = 0.45): genus 1, in a flat grid;
* ``no_surface``  — φ > 0 everywhere: there is nothing to reconstruct.

Each output goes through the suite's own validity rules (:func:`bench.metrics.validity.check_mesh`: non-empty,
finite, world coordinates inside the box, closed, edge-manifold, consistently oriented, outward, on φ = 0) after
a type check (a :class:`methods.Reconstruction` holding a ``trimesh.Trimesh`` and an ``info`` dict).  What
passes:

* sphere, anisotropic, noisy: a valid mesh — raising anything is a violation;
* torus: a valid mesh (of any genus: a method that can only make genus-0 surfaces may wrap the hole, and the
  suite's ``topology_mismatch`` flag reports that in a grid run), or a clear refusal —
  :class:`methods.ReconstructionFailed` or :class:`phantoms.InputError` with a message;
* no_surface: a clear refusal (``InputError``, as :func:`methods.check_volume` raises, or
  ``ReconstructionFailed``) or a :class:`methods.Reconstruction` with an empty mesh.
* any case: skipped, when the method's :meth:`~methods.Method.skip_reason` declines the volume (the reason is
  shown; a grid records such a cell as ``skipped``) — but skipping every case is a violation, as nothing was
  checked.  The method's :meth:`~methods.Method.warm_up` runs before each case, outside its time; either hook
  raising or returning the wrong type is a violation.  A non-empty mesh (a
  surface that is not there) or any other exception (e.g. a ``ValueError`` from deep inside a library) is a
  violation.

Each violation comes with what to fix.  :func:`check_method` returns the per-case results; the command prints
them and exits 1 on any violation.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import tempfile
import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from geometry.mesh import mesh_facts
from methods.contract import (MethodSkipped, Reconstruction, ReconstructionFailed, WrongReturnType, as_reconstruction,
                              check_skip, run_reconstruct, run_warm_up)
from phantoms import InputError, Volume, add_noise, get_phantom

from .metrics.validity import check_mesh
from .run.values import error_text, plain
from .terminal import capture_output, flush_std, redirect_output

__all__ = ["CASES", "CaseResult", "check_method", "refuse_importer", "case_volumes", "HINTS"]

CASES = ("sphere", "anisotropic", "noisy", "torus", "no_surface")

#: what to fix, by the first words of a violation
HINTS = {
    "empty": "return the triangles of the zero level set; an empty mesh is only right when φ has no zero crossing",
    "non-finite": "a vertex has NaN/inf coordinates: look for a division by a zero gradient or normal",
    "bad indices": "faces must index rows of vertices (0-based)",
    "outside the volume": "vertices must be in world coordinates: volume.index_to_world(ijk) = origin + ijk * "
                          "spacing (per axis), with array axis 0 = x; scikit-image's marching_cubes gives "
                          "index coordinates unless you pass spacing= and add volume.origin",
    "open": "the mesh must be closed: build the trimesh with merged vertices (adjacent faces must share vertex "
            "indices, not only positions), e.g. mesh.merge_vertices()",
    "non-manifold": "every edge must be in exactly two faces: drop duplicate faces, split pinched vertices",
    "inconsistently oriented": "neighbouring faces must traverse their shared edge in opposite directions "
                               "(trimesh.repair.fix_winding)",
    "inward": "faces must be counter-clockwise seen from outside (normals up the gradient of φ, φ < 0 inside): "
              "reverse them, faces[:, ::-1]",
    "off the zero set": "the vertices must lie on φ = 0 of the volume you were given (median |φ| ≤ h/2): check "
                        "world coordinates (origin, per-axis spacing), axis order (axis 0 = x) and the sign "
                        "convention (φ < 0 inside)",
    "wrong type": "return methods.Reconstruction(mesh, info) with a trimesh.Trimesh and a dict",
    "raised": "raise phantoms.InputError for a volume the method cannot take and methods.ReconstructionFailed "
              "for a run that failed (both with a message); anything else is a bug",
    "timeout": "the method did not return within the case's time limit (--timeout): look for a loop without a "
               "stopping rule, or raise ReconstructionFailed when it does not converge",
    "crashed": "the method ended its process (a segfault or abort() in compiled code, os._exit, a signal): a "
               "method must return or raise",
    "skipped every case": "skip_reason declined every case's volume (exact signed distances): the checks need "
                          "a method that takes at least one of them",
    "surface": "φ > 0 everywhere: there is no surface; call methods.check_volume(volume, self.name) first "
               "(it raises InputError) or return an empty mesh",
}


@dataclass
class CaseResult:
    """One case: what the method did, how long it took, what it returned, what is wrong.

    Parameters
    ----------
    case : str
        The case's name (one of :data:`CASES`).
    outcome : str
        What the method did: ``mesh``, ``empty mesh``, ``refused``, ``skipped`` (its
        :meth:`~methods.Method.skip_reason` declined the volume), ``raised``, ``wrong type``, ``timeout`` or
        ``crashed``.
    seconds : float
        The case's wall time.
    violations : list of str
        What breaks the contract (each has a :data:`HINTS` entry); none: the case passed (:attr:`passed`).
    notes : list of str
        Remarks that are no violation (a refusal's message, an ``info`` value of the wrong kind, ...).
    info : dict
        The method's ``info``, without its arrays.
    facts : dict
        The returned mesh's facts (vertices, faces, Euler characteristic, ...).
    traceback : str, optional
        The traceback of an exception that is a violation.
    output : str
        What the method wrote on stdout / stderr (a case run in a child process: captured, not shown), at most
        :data:`OUTPUT_KEPT` bytes of it.
    output_bytes : int
        How many bytes it wrote in all.
    warm_up_s : float
        Seconds of the method's :meth:`~methods.Method.warm_up` before the case (not in ``seconds``).
    """

    case: str
    outcome: str = ""
    seconds: float = 0.0
    violations: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    info: dict = field(default_factory=dict)
    facts: dict = field(default_factory=dict)
    traceback: str | None = None
    output: str = ""
    output_bytes: int = 0
    warm_up_s: float = 0.0

    @property
    def passed(self) -> bool:
        return not self.violations


def _sampled(phantom, lower, spacing, shape, centre=(0.0, 0.0, 0.0)) -> Volume:
    """The phantom's exact signed distance, moved to ``centre``, on the grid ``lower + ijk * spacing`` of
    ``shape`` — for the cases whose grid a cubic :meth:`phantoms.Phantom.volume` cannot give."""
    lower, spacing = np.asarray(lower, float), np.asarray(spacing, float)
    axes = [lower[d] + np.arange(shape[d]) * spacing[d] for d in range(3)]
    points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3) - np.asarray(centre, float)
    return Volume(np.asarray(phantom.sdf(points), float).reshape(shape), lower, spacing)


def _ellipsoid(n: int) -> Volume:
    centre, axes = np.array([0.4, -0.3, 0.2]), np.array([1.0, 0.7, 0.5])
    half = axes + 0.35
    spacing = 2 * half / (n - 1) * np.array([1.0, 0.95, 0.9])
    shape = tuple(int(k) for k in np.ceil(2 * half / spacing).astype(int) + 1)
    return _sampled(get_phantom("ellipsoid", axes=tuple(axes)), centre - half, spacing, shape, centre)


def _torus(n: int) -> Volume:
    R, r = 1.0, 0.45
    h = 2 * (R + r + 0.25) / (n - 1)
    shape = (n, n, int(np.ceil(2 * (r + 0.25) / h)) + 1)
    lower = np.array([-(R + r + 0.25), -(R + r + 0.25), -(shape[2] - 1) * h / 2])
    return _sampled(get_phantom("torus", major=R, minor=r), lower, np.full(3, h), shape)


def case_volumes(n: int = 24, seed: int = 0) -> dict[str, tuple[Volume, Volume]]:
    """The volumes of the cases (see the module docstring).

    Parameters
    ----------
    n : int
        About how many grid points per axis.
    seed : int
        Seed of the ``noisy`` case's noise.

    Returns
    -------
    dict of str to (Volume, Volume)
        ``{case: (volume given to the method, clean volume the output is checked against)}``.
    """
    sphere = get_phantom("sphere").volume(n, extent=1.45)
    noisy, _ = add_noise(sphere, "gaussian", 30.0, seed=seed)
    ell, torus = _ellipsoid(n + 4), _torus(n + 4)
    empty = sphere.with_values(np.abs(sphere.values) + 0.5)
    return {"sphere": (sphere, sphere), "anisotropic": (ell, ell), "noisy": (noisy, sphere),
            "torus": (torus, torus), "no_surface": (empty, empty)}


def _info_notes(info: dict) -> list[str]:
    """Known info keys with a value of the wrong kind (see methods.INFO_KEYS)."""
    notes = []
    if "iterations" in info and not isinstance(info["iterations"], (int, np.integer)):
        notes.append(f"info['iterations'] should be an int, got {type(info['iterations']).__name__}")
    if "stop_reason" in info and not isinstance(info["stop_reason"], str):
        notes.append(f"info['stop_reason'] should be a str, got {type(info['stop_reason']).__name__}")
    if "energy_history" in info and np.ndim(info["energy_history"]) != 1:
        notes.append("info['energy_history'] should be a 1-D sequence of floats")
    w = info.get("warnings")
    if w is not None and not (isinstance(w, (list, tuple)) and all(isinstance(s, str) for s in w)):
        notes.append("info['warnings'] should be a list of str")
    return notes


def _mesh_facts(mesh) -> dict:
    try:
        return mesh_facts(mesh)
    except Exception:  # facts are for the reader; a broken mesh is judged by check_mesh
        return {"vertices": len(mesh.vertices), "faces": len(mesh.faces)}


def _judge(res: CaseResult, rec: Reconstruction, clean: Volume, given: Volume | None = None) -> None:
    mesh = rec.mesh
    res.facts = _mesh_facts(mesh)
    empty = len(mesh.vertices) == 0 or len(mesh.faces) == 0
    if res.case == "no_surface":
        res.outcome = "empty mesh" if empty else "mesh"
        if not empty:
            res.violations.append(f"surface: returned a mesh of {len(mesh.faces)} faces for a volume with no "
                                  "zero crossing")
        return
    res.outcome = "mesh"
    res.violations += check_mesh(mesh, clean, given=given)
    if res.case == "torus" and not res.violations and res.facts.get("euler") != 0:
        res.notes.append(f"Euler characteristic {res.facts.get('euler')} (the torus has 0): a grid run flags "
                         "this as topology_mismatch")


def _skip_and_warm_up(method, volume: Volume, res: CaseResult) -> bool:
    """Ask the method whether it takes ``volume`` and let it warm up (not in the case's time); False when the
    case ends there: ``skipped`` with the method's reason, or a violation of either hook."""
    t0 = time.perf_counter()
    try:
        check_skip(method, volume)
        run_warm_up(method)
    except MethodSkipped as exc:
        res.outcome = "skipped"
        res.notes.append(f"skipped: {exc.reason}")
        return False
    except WrongReturnType as exc:
        res.outcome = "wrong type"
        res.violations.append(f"wrong type: {exc}")
        return False
    except Exception as exc:  # noqa: BLE001 - whatever a hook raised is the finding
        res.outcome = "raised"
        res.violations.append(f"raised {error_text(exc)} in skip_reason or warm_up")
        res.traceback = traceback.format_exc()
        return False
    res.warm_up_s = time.perf_counter() - t0
    return True


def run_case(method, case: str, volume: Volume, clean: Volume) -> CaseResult:
    """Run ``method`` on one case volume and judge the result (never raises for what the method does)."""
    res = CaseResult(case)
    if not _skip_and_warm_up(method, volume, res):
        return res
    t0 = time.perf_counter()
    try:
        out = run_reconstruct(method, volume)
        res.seconds = time.perf_counter() - t0
        rec = as_reconstruction(out, method.name)
    except (InputError, ReconstructionFailed) as exc:
        res.seconds = res.seconds or time.perf_counter() - t0
        wrong_type = isinstance(exc, WrongReturnType)
        res.outcome = "wrong type" if wrong_type else "refused"
        res.notes.append(error_text(exc))
        if wrong_type:
            res.violations.append(f"wrong type: {exc}")
        elif case in ("sphere", "anisotropic", "noisy"):
            res.violations.append(f"raised {error_text(exc)} on a volume it must reconstruct")
        return res
    except Exception as exc:  # noqa: BLE001 - whatever the method raised is the finding
        res.seconds = time.perf_counter() - t0
        res.outcome = "raised"
        res.violations.append(f"raised {error_text(exc)}")
        res.traceback = traceback.format_exc()
        return res
    res.info = {k: plain(v) for k, v in rec.info.items() if k not in ("snapshots", "energy_history")}
    res.notes += _info_notes(rec.info)
    _judge(res, rec, clean, None if volume is clean else volume)
    return res


def refuse_importer(method) -> None:
    """Refuse a method that reads a surface made elsewhere (:attr:`methods.Method.imports_surface`, e.g.
    ``mesh_file``): the cases give it volumes to reconstruct, which it does not do, so any verdict on it would be
    about the cases, not the method.

    Parameters
    ----------
    method : methods.Method
        The method, an instance.

    Raises
    ------
    InputError
        One line, for such a method.
    """
    if getattr(method, "imports_surface", False):
        raise InputError(f"method {method.name!r} reads a surface made elsewhere from a file instead of "
                         "reconstructing the volume it is given: check-method's cases cannot judge it (a grid run "
                         "checks and scores its surface like any method's)")


def check_method(method, n: int = 24, cases=CASES, seed: int = 0, timeout: float | None = None) -> list[CaseResult]:
    """Run a method on each of ``cases`` and judge what it returns against the contract of :class:`methods.Method`.

    Parameters
    ----------
    method : methods.Method
        The method, an instance.
    n : int
        About how many grid points per axis.
    cases : sequence of str
        Cases to run, of :data:`CASES`.
    seed : int
        Seed of the ``noisy`` case's noise.
    timeout : float, optional
        Seconds per case.  With it each case runs in a child process (forked, so registered plug-ins come
        along) that is stopped after ``timeout``: a method that hangs is a ``timeout`` violation and one that
        ends its process (``os.abort()``, a segfault, ``os._exit``) a ``crashed`` one, and the remaining cases
        still run.  Without it the cases run in this process (the Python API's default).

    Returns
    -------
    list of CaseResult
        One per case, in the order of ``cases``.

    Raises
    ------
    InputError
        A method that reads a surface made elsewhere (:func:`refuse_importer`).
    """
    refuse_importer(method)
    volumes = case_volumes(n, seed)
    if timeout is None or "fork" not in mp.get_all_start_methods():
        results = []
        for c in cases:                 # in this process: the method's prints kept, not shown raw
            with capture_output() as fd:
                res = run_case(method, c, *volumes[c])
                results.append(_captured(res, fd))
    else:
        results = [_run_case_isolated(method, c, volumes[c], timeout) for c in cases]
    if results and all(r.outcome == "skipped" for r in results):
        results[0].violations.append("skipped every case: nothing was checked")
    return results


#: bytes of a method's own stdout / stderr kept for the report (the rest is counted, not kept)
OUTPUT_KEPT = 4096


def _case_child(conn, method, case: str, volume: Volume, clean: Volume, out_fd: int) -> None:
    try:
        redirect_output(out_fd)
        try:
            res = run_case(method, case, volume, clean)
        except KeyboardInterrupt:          # raised by the method (a real Ctrl-C stops the parent too): a finding
            res = CaseResult(case, outcome="raised")
            res.violations.append("raised KeyboardInterrupt: a method must not raise it (it stops the whole run); "
                                  "raise methods.ReconstructionFailed or phantoms.InputError with a message")
        conn.send(res)
    finally:
        flush_std()
        conn.close()


def _captured(res: CaseResult, fd: int) -> CaseResult:
    """``res`` with the head of what the child wrote on its stdout / stderr (file ``fd``) and its size."""
    res.output_bytes = os.fstat(fd).st_size
    res.output = os.pread(fd, OUTPUT_KEPT, 0).decode("utf-8", "replace") if res.output_bytes else ""
    return res


def _run_case_isolated(method, case: str, volumes, timeout: float) -> CaseResult:
    """:func:`run_case` in a forked child, stopped after ``timeout`` seconds; its death is the finding.  What the
    method writes on stdout / stderr goes to a temporary file, not the terminal (:attr:`CaseResult.output`)."""
    with tempfile.TemporaryFile() as out:
        return _captured(_run_in_child(method, case, volumes, timeout, out.fileno()), out.fileno())


def _run_in_child(method, case: str, volumes, timeout: float, out_fd: int) -> CaseResult:
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    t0 = time.perf_counter()
    proc = ctx.Process(target=_case_child, args=(send, method, case, *volumes, out_fd), daemon=True)
    proc.start()
    send.close()
    result = None
    try:
        if recv.poll(timeout):
            result = recv.recv()
    except (EOFError, OSError):            # the child died before sending: judged below
        pass
    finally:
        if proc.is_alive() and result is None:
            proc.kill()
        proc.join(5)
        recv.close()
    if result is not None:
        return result
    res = CaseResult(case, seconds=time.perf_counter() - t0)
    if proc.exitcode is None or proc.exitcode == -signal.SIGKILL and res.seconds >= timeout:
        res.outcome = "timeout"
        res.violations.append(f"timeout: no result after {timeout:g} s (the case was stopped)")
    else:
        code = proc.exitcode
        how = f"signal {signal.Signals(-code).name}" if code < 0 else f"exit code {code}"
        res.outcome = "crashed"
        res.violations.append(f"crashed: the method ended its process ({how}) instead of returning or raising")
    return res


def hint(violation: str) -> str:
    """What to fix for one violation."""
    for key, text in HINTS.items():
        if violation.startswith(key):
            return text
    return ""
