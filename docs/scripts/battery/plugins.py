"""Plug-ins run through every command that takes a method: ones that write to their input (cause 5), that end
the process at import (6), that fail in every way a method can (11), that put terminal controls in what they
say (13), and that tamper with their run folder (2).  Each is contained: a failed row with its reason, one line
and a non-zero exit, never a traceback, a silent exit 0 or a raw control on the terminal."""

from __future__ import annotations

from pathlib import Path

from . import plugin_source as src
from .core import Case, Ctx, Result, exits_ok, failed_row, first, no_traceback, one_line, raw_controls, rows

SPHERE = ("--phantoms", "sphere", "--n", "16", "--noise", "none")


def modules(ctx: Ctx) -> Path:
    """Every plug-in module written into the plug-in folder, once."""
    def make() -> Path:
        for name, text in (("bat_writers", src.module_writers()), ("bat_failing", src.module_failing()),
                           ("bat_noisy", src.module_noisy()), ("bat_named", src.module_named()),
                           ("bat_tamper", src.module_tamper()), *src.AT_IMPORT.items()):
            (ctx.plugins / f"{name}.py").write_text(text)
        return ctx.plugins
    return ctx.once("plugins", make)


def volume(ctx: Ctx) -> Path:
    """A sphere at N = 16 as .npz, made once."""
    def make() -> Path:
        path = ctx.root / "sphere16.npz"
        res = ctx.bench("volume", "sphere", "--n", "16", "-o", str(path))
        if res.rc != 0:
            raise RuntimeError(res.show())
        return path
    return ctx.once("sphere16", make)


def grid_run(ctx: Ctx, module: str, names: list[str], tag: str) -> tuple[Path, Result]:
    """One run of every method of ``names`` (from ``module``) on the sphere at N = 16, made once."""
    def make():
        modules(ctx)
        out = ctx.root / "plugin_runs" / tag
        args = [a for n in names for a in ("--add-method", n)]
        res = ctx.bench("run", *SPHERE, "--import", module, "--method", "marching_cubes", *args, "--out", str(out),
                        "--jobs", "2", "--timeout", "60", timeout=600)
        return out, res
    return ctx.once(f"grid.{tag}", make)


def reconstruct(ctx: Ctx, module: str, name: str, *extra: str) -> Result:
    modules(ctx)
    return ctx.bench("reconstruct", str(volume(ctx)), "-m", name, "--import", module, "-o",
                     str(ctx.root / f"{name}.ply"), *extra, timeout=120)


def check_method(ctx: Ctx, module: str, name: str) -> Result:
    modules(ctx)
    return ctx.bench("check-method", name, "--import", module, "--case", "sphere", "--n", "16", "--timeout", "60",
                     timeout=180)


# ------------------------------------------------------------------------------------------------ cause 5
def _not_ok_row(out: Path, label: str) -> str | None:
    found = [r for r in rows(out) if r.get("label") == label]
    if not found:
        return f"no row for {label}"
    r = found[0]
    if r["status"] == "ok":
        return f"{label}: an ok row (hausdorff_h {r['hausdorff_h']}, sdf_rms_h {r['sdf_rms_h']}): a write to " \
               "the volume went unnoticed"
    return None


def _judged_on_the_input(out: Path, label: str) -> str | None:
    """A method that wrote only into the derived grids, its mesh made from the input's φ: the suite must judge
    that mesh against the input (an ok row with marching cubes' fidelity), not against the grids it shifted."""
    found = [r for r in rows(out) if r.get("label") == label]
    if not found:
        return f"no row for {label}"
    r = found[0]
    if r["status"] != "ok" or float(r["sdf_rms_h"]) > 0.5:
        return f"{label}: status {r['status']}, sdf_rms_h {r['sdf_rms_h']}: the right mesh judged against the " \
               "grids the method shifted"
    return None


#: writers whose write reaches only derived data: the suite rebuilds it, their (right) mesh is judged as right
_DERIVED_ONLY = ("rw_channels",)


def writer_cases() -> list[Case]:
    """A method that writes to its volume (values, origin, spacing) fails or is invalid, never ok; one that
    writes into the derived interpolation grids is judged against the input's own φ."""
    out: list[Case] = []
    names = list(src.WRITERS)
    for name in names:
        def run(ctx, name=name):
            folder, res = grid_run(ctx, "bat_writers", names, "writers")
            check = _judged_on_the_input if name in _DERIVED_ONLY else _not_ok_row
            return first(exits_ok(res), check(folder, name))

        def rec(ctx, name=name):
            res = reconstruct(ctx, "bat_writers", name)
            bad = no_traceback(res)
            if name in _DERIVED_ONLY:
                return bad or (None if res.rc == 0 and "valid:        yes" in res.out else
                               f"exit {res.rc}: the right mesh was not judged valid")
            if bad or res.rc in (1, 2):
                return bad
            return f"exit {res.rc}: the method's write went unnoticed ({res.out.strip().splitlines()[-1:]})"
        out += [Case("5", f"run: {name}", run), Case("5", f"reconstruct: {name}", rec)]
    for name in ("rw_iadd", "rw_flags", "rw_origin"):
        out.append(Case("5", f"check-method: {name}", lambda ctx, name=name: first(
            no_traceback(r := check_method(ctx, "bat_writers", name)), None if r.rc == 1 else f"exit {r.rc}")))
    return out


# ------------------------------------------------------------------------------------------------ cause 6
def import_cases() -> list[Case]:
    """A module that exits or breaks at import: exit 2, one line naming the module, for every command."""
    out: list[Case] = []
    for module in src.AT_IMPORT:
        commands = {
            "methods": ("methods", "--import", module),
            "run": ("run", *SPHERE, "--method", "marching_cubes", "--import", module, "--out", f"imp_{module}"),
            "check-method": ("check-method", "marching_cubes", "--import", module),
            "reconstruct": ("reconstruct", "sphere16.npz", "-m", "marching_cubes", "--import", module, "-o",
                            f"{module}.ply"),
        }
        for command, args in commands.items():
            def check(ctx, args=args, module=module, command=command):
                modules(ctx)
                volume(ctx)
                res = ctx.bench(*args, timeout=120)
                # a KeyboardInterrupt at import cannot be told from the user's Ctrl-C: 130, 'interrupted'
                reason = one_line(res, "interrupted", rc=130) if module == "bat_kbint" else one_line(res, module)
                if not reason and command == "run" and (ctx.root / f"imp_{module}" / "results.csv").exists():
                    return "a results.csv was written although the import failed"
                return reason
            out.append(Case("6", f"{command}: {module}", check))
    return out


# ------------------------------------------------------------------------------------------------ cause 11
STATUSES = ("failed", "invalid", "timeout")


def failing_cases() -> list[Case]:
    """Each failing method: reconstruct exits 1 or 2 without a traceback (and writes no bad mesh), check-method
    finds it (exit 1, no child traceback), a grid gives a failed or invalid row with its reason."""
    out: list[Case] = []
    names = list(src.FAILING)
    for name in names:
        def rec(ctx, name=name):
            res = reconstruct(ctx, "bat_failing", name)
            errors = [line for line in res.err_lines if line.startswith("error:")]
            return first(no_traceback(res), raw_controls(res),
                         None if res.rc in (1, 2) else f"exit {res.rc}: {res.show()}",
                         None if len(res.err) < 20000 else f"{len(res.err)} characters on stderr",
                         None if len(errors) <= 1 else f"{len(errors)} error lines",
                         "the mesh with a face naming a missing vertex was written"
                         if name == "f_bad_faces" and (ctx.root / f"{name}.ply").exists() else None)

        def chk(ctx, name=name):
            res = check_method(ctx, "bat_failing", name)
            return first(no_traceback(res), None if "ForkProcess" not in res.out + res.err else "a child traceback",
                         None if res.rc == 1 else f"exit {res.rc}: {res.show()}", raw_controls(res))

        def run(ctx, name=name):
            folder, res = grid_run(ctx, "bat_failing", names, "failing")
            found = [r for r in rows(folder) if r.get("label") == name]
            if found and found[0]["status"] == "invalid":
                return exits_ok(res)
            return first(exits_ok(res), failed_row(folder, name, statuses=STATUSES), _has_reason(found))
        out += [Case("11", f"reconstruct: {name}", rec), Case("11", f"check-method: {name}", chk),
                Case("11", f"run: {name}", run)]
    return out


def _has_reason(found: list[dict]) -> str | None:
    if found and len((found[0].get("error") or "").strip()) < 5:
        return f"a {found[0]['status']} row without a reason"
    return None


# ------------------------------------------------------------------------------------------------ cause 13
def terminal_cases() -> list[Case]:
    """Every text a plug-in provides, and a file name, shown escaped: no raw control on the terminal."""
    out: list[Case] = []

    def clean(res: Result, rc=None) -> str | None:
        return first(no_traceback(res), raw_controls(res),
                     None if len(res.out) + len(res.err) < 200_000 else f"{len(res.out)} characters on stdout",
                     None if rc is None or res.rc in rc else f"exit {res.rc}: {res.show()}")
    out.append(Case("13", "methods: every plug-in text", lambda ctx: clean(
        ctx.bench("methods", "--import", "bat_noisy", cwd=modules(ctx)), (0,))))
    out.append(Case("13", "methods NAME: description, parameter docs and choices", lambda ctx: clean(
        ctx.bench("methods", "t_described", "--import", "bat_noisy", cwd=modules(ctx)), (0,))))
    out.append(Case("13", "methods: a registry name holding controls", lambda ctx: clean(
        ctx.bench("methods", "--import", "bat_named", cwd=modules(ctx)))))
    out.append(Case("13", "methods: an import error holding controls", lambda ctx: clean(
        ctx.bench("methods", "--import", "bat_controls", cwd=modules(ctx)), (2,))))
    for name in src.NOISY:
        out.append(Case("13", f"reconstruct: {name}", lambda ctx, name=name: clean(
            reconstruct(ctx, "bat_noisy", name), (0, 1))))
        out.append(Case("13", f"check-method: {name}", lambda ctx, name=name: clean(
            check_method(ctx, "bat_noisy", name), (0, 1))))
    out.append(Case("13", "run: every noisy plug-in (the terminal)", lambda ctx: clean(
        grid_run(ctx, "bat_noisy", list(src.NOISY), "noisy")[1], (0,))))
    out.append(Case("13", "run: the report runs no injected script", _no_script))
    for label, fname in (("ESC", "e\x1b[2Jvil.npz"), ("BEL and OSC", "t\x1b]0;x\x07.npz"),
                         ("U+202E", "r\u202egpj.npz")):
        def info(ctx, fname=fname):
            path = ctx.root / "names" / fname
            path.parent.mkdir(exist_ok=True)
            path.write_bytes(volume(ctx).read_bytes())
            return first(clean(ctx.bench("info", str(path)), (0,)),
                         clean(ctx.bench("info", str(path) + ".missing"), (2,)))
        out.append(Case("13", f"info: a file name with {label} (read and missing)", info))
    return out


def _no_script(ctx: Ctx) -> str | None:
    folder, _ = grid_run(ctx, "bat_noisy", list(src.NOISY), "noisy")
    page = (folder / "index.html").read_text(errors="replace") if (folder / "index.html").exists() else ""
    if not page:
        return "no index.html"
    for bad in ("<script>alert(1)</script>", "<img src=x onerror"):
        if bad in page:
            return f"the page holds the plug-in's raw {bad!r}"
    return None


# ------------------------------------------------------------------------------------------------ cause 2
def tamper_cases() -> list[Case]:
    """A plug-in that deletes config.json leaves a resumable folder; one that plants a record plants nothing."""
    def deletes(ctx):
        modules(ctx)
        out = ctx.root / "tamper_cfg"
        res = ctx.bench("run", *SPHERE, "--import", "bat_tamper", "--method", "marching_cubes", "--add-method",
                        f"tamper_config:folder={out}", "--out", str(out), "--jobs", "1", timeout=180)
        again = ctx.bench("run", "--resume", "--out", str(out), "--jobs", "1", "--import", "bat_tamper",
                          timeout=180)
        return first(exits_ok(res), exits_ok(again), None if len(rows(out)) == 2 else "rows lost")

    def plants(ctx):
        modules(ctx)
        out = ctx.root / "tamper_rec"
        res = ctx.bench("run", *SPHERE, "--import", "bat_tamper", "--method", "marching_cubes", "--add-method",
                        f"tamper_record:folder={out}", "--out", str(out), "--jobs", "1", timeout=180)
        planted = [r for r in rows(out) if r["cell_id"] == "planted"]
        return first(exits_ok(res), "the planted record is a row" if planted else None,
                     exits_ok(ctx.bench("table", str(out))),
                     None if (out / "cells" / "planted.json").exists() is False else "planted.json still in cells/")
    return [Case("2", "a plug-in deletes config.json mid-run: --resume completes", deletes),
            Case("2", "a plug-in plants a sealed record: set aside, not a row", plants)]


def cases() -> list[Case]:
    return writer_cases() + import_cases() + failing_cases() + terminal_cases() + tamper_cases()
