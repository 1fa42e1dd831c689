"""``python -m bench check-method NAME [--import MODULE] [--set key=value ...]``: the method contract, tested.

Runs the method on the small volumes of :mod:`bench.check`, prints per case the outcome, the time, the mesh
facts, the method's ``info`` and every violation with what to fix; exit code 1 on any violation, 0 when the
method honours the contract, 2 on bad input (unknown method or parameter, a module that does not import).
"""

from __future__ import annotations

from ..check import CASES, OUTPUT_KEPT, check_method, hint, refuse_importer
from ..terminal import printable
from .methods import add_import_option, import_modules, parse_assignments
from .validators import case_timeout, int_between

HELP = """\
Run a method on small test volumes (sphere; anisotropic off-centre ellipsoid; noisy sphere; torus; a volume
with no zero crossing) and check each output against the contract every method must honour: a
methods.Reconstruction holding a closed, edge-manifold, consistently and outward oriented trimesh in world
coordinates on phi = 0, with finite vertices (the suite's validity rules). On the volume with no surface the
method must refuse clearly (phantoms.InputError / methods.ReconstructionFailed) or return an empty mesh; on the
torus a clear refusal is accepted too. Exit code 1 on any violation, with what to fix."""


def _short(value) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    text = str(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _print_case(r, verbose: bool) -> None:
    verdict = "ok  " if r.passed else "FAIL"
    what = r.outcome
    if r.facts:
        what += f", {r.facts.get('faces', '?')} faces, euler {r.facts.get('euler', '?')}"
    if r.warm_up_s >= 0.001:
        what += f" (after warm_up: {r.warm_up_s:.3f} s, not counted)"
    print(f"  {r.case:<12} {verdict}  {r.seconds:7.3f} s  {what}")
    for note in r.notes:
        print(printable(f"  {'':<12}       note: {note}"))
    if r.info:
        items = ", ".join(f"{k}={_short(v)}" for k, v in r.info.items())
        print(printable(f"  {'':<12}       info: {items}"))
    for v in r.violations:
        print(printable(f"  {'':<12}       violation: {v}"))
        fix = hint(v)
        if fix:
            print(f"  {'':<12}         fix: {fix}")
    if verbose and r.traceback:
        print(printable(r.traceback))
    _print_output(r)


def _print_output(r) -> None:
    """The head of what the method wrote on stdout / stderr, control characters shown, with how much was cut."""
    if not r.output_bytes:
        return
    shown = min(OUTPUT_KEPT, r.output_bytes)
    cut = f"; the first {shown} shown, {r.output_bytes - shown} cut" if r.output_bytes > shown else ""
    print(f"  {'':<12}       output: the method wrote {r.output_bytes} bytes on stdout / stderr{cut}:")
    for line in r.output.splitlines():
        print(printable(f"  {'':<12}         | {line}"))


def _cmd_check(args) -> int:
    from methods import get_method

    import_modules(args)
    method = get_method(args.name, **parse_assignments(args.set))
    refuse_importer(method)         # before the heading: nothing is checked
    cases = args.case or list(CASES)
    settings = ", ".join(f"{k}={v!r}" for k, v in method.config.items())
    print(printable(f"check-method {method.name} ({settings or 'no parameters'}), N = {args.n}"))
    results = check_method(method, n=args.n, cases=cases, timeout=args.timeout or None)
    for r in results:
        _print_case(r, args.verbose)
    bad = [r.case for r in results if not r.passed]
    total = sum(r.seconds for r in results)
    if bad:
        print(f"FAIL: {len(bad)} of {len(results)} cases violate the method contract ({', '.join(bad)}); "
              f"{total:.2f} s in the method")
        return 1
    skipped = sum(r.outcome == "skipped" for r in results)
    print(f"ok: {len(results)} cases honour the method contract{f' ({skipped} skipped)' if skipped else ''}; "
          f"{total:.2f} s in the method")
    return 0


def register(subparsers) -> None:
    import argparse

    p = subparsers.add_parser("check-method", help="check that a method honours the method contract",
                              description=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("name", metavar="NAME", help="method name (see: python -m bench methods)")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="set a method parameter (repeatable)")
    add_import_option(p)
    p.add_argument("--n", type=int_between(12, 128), default=24, help="grid points per axis of the test volumes "
                                                              "(default 24)")
    p.add_argument("--case", action="append", choices=CASES, help="run only this case (repeatable)")
    p.add_argument("--timeout", type=case_timeout, default=120.0, metavar="S",
                   help="seconds per case before the method is stopped and the case is a violation; each case "
                        "runs in its own process, so a crash is reported too (0 = no limit, in this process; "
                        "default 120)")
    p.add_argument("--verbose", "-v", action="store_true", help="print the traceback of a method that raised")
    p.set_defaults(func=_cmd_check)
