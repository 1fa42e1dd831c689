"""``python -m bench methods`` and ``python -m bench reconstruct``.

* ``methods`` lists every method the registry finds (built-ins, entry points of group
  ``levelset_bench.methods``, registered ones) with its parameters, types, defaults, ranges and docs.
* ``reconstruct IN --method NAME [--set key=value ...] -o OUT.ply`` reads any volume the suite reads
  (:func:`phantoms.load_volume`), runs the method, writes the mesh (PLY/OBJ/STL by suffix) and prints the
  mesh facts (vertices, faces, watertight, Euler characteristic, signed volume, time) and the method's own
  scalar facts (iterations, stop reason, ...).  The time is ``reconstruct``'s alone, after the method's
  ``warm_up``; a volume its ``skip_reason`` declines is one line, exit code 2.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from phantoms import InputError, load_volume

from geometry.files import atomic_write

from ..metrics.validity import check_mesh
from ..terminal import captured_head, printable, show_captured
from .outputs import check_outputs, refuse_non_finite, write_mesh

MESH_SUFFIXES = {".ply": "ply", ".obj": "obj", ".stl": "stl"}


def _param_line(key: str, spec) -> str:
    typ = getattr(spec.type, "__name__", str(spec.type))
    extra = []
    if spec.choices is not None:
        extra.append("one of " + "|".join(str(c) for c in spec.choices))
    if spec.min is not None or spec.max is not None:
        lo = "-inf" if spec.min is None else f"{spec.min:g}"
        hi = "inf" if spec.max is None else f"{spec.max:g}"
        extra.append(f"range [{lo}, {hi}]")
    bounds = f" ({'; '.join(extra)})" if extra else ""
    default = "auto" if spec.default is None else repr(spec.default)
    return printable(f"    {key:<17} {typ:<6} default {default:<10} {spec.doc}{bounds}")  # plug-in text


def add_import_option(p) -> None:
    """``--import MODULE`` (repeatable): import a module that registers methods before the name is resolved."""
    p.add_argument("--import", dest="imports", action="append", metavar="MODULE", default=None,
                   help="import MODULE first (e.g. one that calls methods.register_method); repeatable")


def import_modules(args) -> None:
    """Import the ``--import`` modules (InputError naming a module that fails to import)."""
    from methods import import_plugins

    from ..imports import probe_imports

    probe_imports(args.imports or ())       # one that ends its process at import: named, not a silent exit
    import_plugins(args.imports or ())


def _cmd_methods(args) -> int:
    import warnings

    from methods import available_methods

    import_modules(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        methods = available_methods()
    names = [args.name] if args.name else list(methods)
    for name in names:
        if name not in methods:
            raise InputError(f"unknown method {name!r}; valid methods: {', '.join(methods)}")
    for i, name in enumerate(names):
        cls = methods[name]
        if i:
            print()
        # the name, description, class and parameter docs are a plug-in's text: shown, never obeyed
        origin = f"{cls.__module__}:{cls.__qualname__}"
        print(printable(f"{name} — {cls.description or '(no description)'}"))
        print(printable(f"  class: {origin}"))
        try:
            missing = cls.missing()
        except Exception:  # noqa: BLE001 - a plug-in's own override must not break the listing
            missing = None
        if missing:
            print(printable(f"  unavailable: {missing}"))
        if cls.params:
            print("  parameters (set with --set key=value):")
            for key, spec in cls.params.items():
                print(_param_line(key, spec))
        else:
            print("  parameters: none")
    for w in caught:
        print(printable(f"note: {w.message}"))
    return 0


def parse_assignments(items: list[str] | None) -> dict[str, str]:
    """``["a=1", "b=x"]`` → ``{"a": "1", "b": "x"}`` (values stay strings; the method's Params convert)."""
    out: dict[str, str] = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise InputError(f"--set expects key=value, got {item!r}")
        if key in out:
            raise InputError(f"--set gives parameter {key!r} twice")
        out[key] = value.strip()
    return out


def _fmt(value) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.6g}"
    return str(value)


def _in_child(conn, fn, method, volume, out_fd: int) -> None:
    from ..terminal import redirect_output

    try:
        redirect_output(out_fd)             # the method's own prints: shown escaped by the parent
        conn.send(("ok", fn(method, volume)))
    except BaseException as exc:  # noqa: BLE001 — sent back and judged in the parent
        try:
            conn.send(("raised", exc))
        except Exception:  # noqa: BLE001 — an exception that does not pickle
            conn.send(("raised", RuntimeError(f"{type(exc).__name__}: {exc}")))
    finally:
        conn.close()


#: bytes of a method's own output ``reconstruct`` shows (escaped)
OUTPUT_SHOWN = 4096


#: seconds before the first "still running" line of a long reconstruction, and between the next ones
TICK_FIRST_S, TICK_EVERY_S = 5.0, 15.0


def wait_with_ticks(conn, name: str) -> None:
    """Wait until ``conn`` (the child's pipe) has the method's result, saying on stderr every
    :data:`TICK_EVERY_S` seconds (the first after :data:`TICK_FIRST_S`) that the method is still running and for
    how long — a reconstruction of minutes does not run in silence."""
    t0 = time.perf_counter()
    wait = TICK_FIRST_S
    while not conn.poll(wait):
        print(printable(f"reconstruct: method {name!r} still running ({time.perf_counter() - t0:.0f} s)"),
              file=sys.stderr, flush=True)
        wait = TICK_EVERY_S


def _isolated(fn, method, volume):
    """``fn(method, volume)`` in a forked child (where fork exists): a method that aborts or segfaults ends the
    child, not this command, and is one line naming the signal."""
    import multiprocessing as mp
    import signal

    from methods import ReconstructionFailed

    if "fork" not in mp.get_all_start_methods():
        return fn(method, volume)
    ctx = mp.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    with tempfile.TemporaryFile() as out:
        proc = ctx.Process(target=_in_child, args=(send, fn, method, volume, out.fileno()), daemon=True)
        proc.start()
        send.close()
        try:
            wait_with_ticks(recv, method.name)
            kind, value = recv.recv()
        except (EOFError, OSError):
            proc.join()
            code = proc.exitcode
            how = (f"signal {signal.Signals(-code).name}" if code is not None and code < 0 else f"exit code {code}")
            raise ReconstructionFailed(f"method {method.name!r} ended its process ({how}: an abort or a crash in "
                                       "compiled code) instead of returning or raising") from None
        finally:
            recv.close()
            proc.join()
            show_captured(*captured_head(out.fileno(), OUTPUT_SHOWN), OUTPUT_SHOWN, f"method {method.name!r}")
    if kind == "raised":
        if isinstance(value, KeyboardInterrupt):     # the child's own: the user's Ctrl-C interrupts this process
            raise ReconstructionFailed(f"method {method.name!r} raised KeyboardInterrupt instead of returning or "
                                       "raising an error (a method must not: it reads as the user's Ctrl-C)")
        raise value
    return value


def _guarded(fn, method, volume):
    """``fn(method, volume)`` in a child process (:func:`_isolated`); a plug-in's own exception (MemoryError, a
    bug, a missing ``reconstruct``) or its crash becomes one :class:`methods.ReconstructionFailed` line naming
    the method instead of a traceback or a silent exit code."""
    from methods import ReconstructionFailed

    try:
        return _isolated(fn, method, volume)
    except (InputError, ReconstructionFailed, KeyboardInterrupt):
        raise
    except MemoryError:
        raise ReconstructionFailed(f"method {method.name!r} ran out of memory") from None
    except Exception as exc:  # noqa: BLE001 — a plug-in may raise anything
        text = " ".join(str(exc).split()) or "(no message)"
        raise ReconstructionFailed(f"method {method.name!r} failed: {type(exc).__name__}: {text}") from None


def _timed_run(method, volume):
    """``(what reconstruct returned, its seconds)``, after the method said it takes ``volume``
    (:class:`methods.MethodSkipped` if not) and warmed up outside the time."""
    from methods.contract import check_skip, run_reconstruct, run_warm_up

    check_skip(method, volume)
    run_warm_up(method)
    t0 = time.perf_counter()
    out = run_reconstruct(method, volume)
    return out, time.perf_counter() - t0


def spacing_text(spacing) -> str:
    """A grid's spacing: one number when it is the same on every axis, else all three (``0.8 × 0.8 × 1.5``)."""
    sp = [float(x) for x in np.broadcast_to(np.asarray(spacing, float), (3,))]
    return f"{sp[0]:.6g}" if len({f"{x:.6g}" for x in sp}) == 1 else " × ".join(f"{x:.6g}" for x in sp)


def _cmd_reconstruct(args) -> int:
    from methods import get_method
    from methods.contract import as_reconstruction
    from geometry.mesh import mesh_facts

    out = Path(args.output)
    suffix = out.suffix.lower()
    if suffix not in MESH_SUFFIXES:
        raise InputError(f"output {str(out)!r}: unknown mesh format {suffix or '(none)'!r}; "
                         f"use one of {', '.join(MESH_SUFFIXES)}")
    import_modules(args)
    method = get_method(args.method, **parse_assignments(args.set))  # bad names/params fail before I/O
    volume = load_volume(args.input, mask=True if args.mask else None)
    check_outputs(out, args.info_json)  # a bad output path fails before the method runs
    returned, wall = _guarded(_timed_run, method, volume)       # declined: one line, exit 2
    rec = as_reconstruction(returned, args.method)  # wrong type, sys.exit: exit 1
    mesh = getattr(rec, "mesh", None)
    if mesh is None:
        raise InputError(f"method {args.method!r} returned no mesh")
    from ..run.cell import degenerate_reasons

    invalid = check_mesh(mesh, volume) or degenerate_reasons(mesh)     # a closed mesh of zero area is no surface
    # an empty mesh, one with NaN / infinite vertices or faces naming vertices that do not exist is invalid too,
    # and there is nothing sensible to write
    unusable = any(r.startswith(("empty", "non-finite", "bad indices")) for r in invalid)
    if unusable or len(mesh.faces) == 0 or len(mesh.vertices) == 0 or not np.isfinite(np.asarray(mesh.vertices)).all():
        print(f"error: method {args.method!r} returned an invalid mesh: {'; '.join(invalid)} — nothing written",
              file=sys.stderr)
        return 1
    refuse_non_finite(mesh, args.method)      # finite but beyond float32: inf once written as PLY / STL
    write_mesh(mesh, out, MESH_SUFFIXES[suffix])
    facts = mesh_facts(mesh)
    settings = ", ".join(f"{k}={v!r}" for k, v in method.config.items())
    print(printable(f"method:       {method.name} ({settings})"))
    print(f"input:        {printable(args.input)} (shape {volume.shape}, spacing {spacing_text(volume.spacing)})")
    print(f"wrote:        {out}")
    print(f"vertices:     {facts['vertices']}")
    print(f"faces:        {facts['faces']}")
    print(f"watertight:   {_fmt(facts['watertight'])}")
    print(f"euler:        {facts['euler']}")
    print(f"components:   {facts['components']}")
    print(f"volume:       {facts['signed_volume']:.6g} (signed; > 0 = outward faces)")
    print(f"time:         {wall:.3f} s")
    print(f"valid:        {'no — ' + '; '.join(invalid) if invalid else 'yes'}")
    for warning in rec.info.get("warnings") or []:
        print(printable(f"warning: {warning}"), file=sys.stderr)
    scalars = {k: v for k, v in rec.info.items()
               if not k.startswith("mesh_") and isinstance(v, (bool, int, float, str, np.generic))}
    for key, value in scalars.items():
        print(printable(f"  {key + ':':<22}{_fmt(value)}"))
    if args.info_json:
        atomic_write(args.info_json, json.dumps(
            {"method": args.method, "params": method.config, "wall_s": wall, "mesh": facts,
             "valid": not invalid, "invalid_reasons": invalid,
             "info": {k: (v.item() if isinstance(v, np.generic) else v) for k, v in scalars.items()}},
            indent=2, default=str))
    if invalid:
        print(f"error: method {args.method!r} returned an invalid mesh (written to {out} for inspection): "
              f"{'; '.join(invalid)}", file=sys.stderr)
        return 1
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("methods", help="list the reconstruction methods and their parameters",
                              description="List every reconstruction method (built-ins and plug-ins of the "
                                          "entry-point group levelset_bench.methods) with its parameters, "
                                          "types, defaults, ranges and documentation.")
    p.add_argument("name", nargs="?", help="show only this method")
    add_import_option(p)
    p.set_defaults(func=_cmd_methods)

    p = subparsers.add_parser("reconstruct", help="reconstruct a mesh from a volume file",
                              description="Read a volume (.npz, .npy, .nii, .nii.gz; binary masks become "
                                          "signed distance volumes), run a method, write the mesh (.ply, .obj "
                                          "or .stl by suffix) and print its facts.")
    p.add_argument("input", metavar="IN", help="volume file")
    p.add_argument("--method", "-m", required=True, help="method name (see: python -m bench methods)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="set a method parameter (repeatable)")
    p.add_argument("-o", "--output", required=True, help="output mesh: .ply, .obj or .stl")
    p.add_argument("--mask", action="store_true", help="require the input to be a binary mask")
    p.add_argument("--info-json", metavar="FILE", help="also write the mesh and method facts as JSON")
    add_import_option(p)
    p.set_defaults(func=_cmd_reconstruct)
