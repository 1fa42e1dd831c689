"""``python -m bench run`` (the benchmark grid) and ``python -m bench report`` (re-render a run's report)."""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
from pathlib import Path

from geometry.files import WriteError, atomic_write
from phantoms import InputError

from ..config import RunConfig, builtin_config, config_from_dict, load_config, parse_degrade_list, parse_noise_spec
from ..specs import parse_method_spec
from ..terminal import printable
from .validators import int_list, nonneg_float, positive_int

RUN_HELP = """\
Run a phantom x noise x method grid and write results.csv, run.json and index.html into --out.
Without --config or --quick it runs the paper's grid (bench/configs/paper.toml).
Grid options (--phantoms, --n, --noise, --seeds, --method, --add-method) override the config.
Exit code 0 when the grid ran (failed cells are rows of the results), 2 on bad input."""


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "run", help="run the benchmark grid (default: the paper's) and write the report",
        description=RUN_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    src = p.add_mutually_exclusive_group()
    src.add_argument("--config", metavar="FILE.toml", help="grid configuration (see bench/configs/*.toml)")
    src.add_argument("--quick", action="store_true", help="the CI-size grid (bench/configs/quick.toml)")
    p.add_argument("--out", metavar="DIR", help="output folder (default reports/<timestamp>/)")
    p.add_argument("--jobs", type=positive_int, default=None, help="worker processes (default: CPU cores)")
    p.add_argument("--resume", action="store_true",
                   help="skip the cells already finished in --out (with neither --config nor --quick, "
                        "the folder's own config is used)")
    p.add_argument("--allow-mixed-code", action="store_true",
                   help="with --resume: accept cells computed by another version of the suite (run.json and "
                        "the report then say so)")
    p.add_argument("--retry-failed", action="store_true", help="with --resume: rerun failed and timed-out cells")
    p.add_argument("--timeout", type=nonneg_float, default=None, metavar="S",
                   help="seconds per cell before it is killed and recorded as timeout (0 = none; "
                        "default: the config's run.timeout)")
    p.add_argument("--method-timeout", type=nonneg_float, default=None, metavar="S",
                   help="seconds for the method alone (method.reconstruct; 0 = none; default: run.method_timeout)")
    p.add_argument("--score-timeout", type=nonneg_float, default=None, metavar="S",
                   help="seconds for the scoring alone (validity check and metrics, after the method returned; "
                        "0 = none; default: run.score_timeout)")
    p.add_argument("--memory-limit", type=nonneg_float, default=None, metavar="GB",
                   help="address space per cell process in GB (2**30 bytes); a cell over it is a failed row "
                        "('memory limit ... exceeded in the method / in scoring') and the run goes on (0 = none; "
                        "default: the config's run.memory_limit, else 75%% of the physical memory / --jobs)")
    p.add_argument("--force", action="store_true",
                   help="run the cells whose method's cost estimate exceeds their time limit (otherwise each is a "
                        "failed row at once: 'estimated X min > timeout Y min'; default: the config's run.force)")
    p.add_argument("--save-meshes", action="store_true", help="write each cell's mesh to DIR/meshes/<cell_id>.ply")
    p.add_argument("--no-report", action="store_true", help="skip index.html")
    p.add_argument("--dry-run", action="store_true", help="validate, list the cells and exit")
    g = p.add_argument_group("grid overrides")
    g.add_argument("--phantoms", metavar="A,B", help="comma-separated phantoms; a comma inside a spec's ?query "
                   "belongs to it (volume:seg.nii.gz?labels=1,3,sphere: labels 1 and 3, then the sphere)")
    g.add_argument("--n", type=int_list, metavar="N[,N]", help="grid points per axis")
    g.add_argument("--noise", metavar="SPEC", help="e.g. none,gaussian,uniform@40 (no @: the paper's SNR)")
    g.add_argument("--degrade", metavar="SPEC", help="input degradations, e.g. none,mask,partial_volume,"
                   "thick_slices@3+mask,label_noise@0.1+mask (docs/PHANTOMS.md)")
    g.add_argument("--seeds", type=int_list, metavar="S[,S]", help="noise seeds")
    g.add_argument("--method", action="append", metavar="SPEC", default=None,
                   help="replace the config's methods; SPEC = [LABEL=]NAME[:key=value,...]; repeatable")
    g.add_argument("--add-method", action="append", metavar="SPEC", default=None,
                   help="add a method to the config's ones (same SPEC); repeatable")
    g.add_argument("--import", dest="imports", action="append", metavar="MODULE", default=None,
                   help="import MODULE first (e.g. one that calls methods.register_method); repeatable")
    g.add_argument("--n-samples", type=positive_int, default=None, help="surface samples for the distances")
    e = p.add_argument_group("executor")
    e.add_argument("--executor", choices=("local", "dask"), default="local",
                   help="local: a process pool on this machine (default); dask: one Dask task per cell "
                        "(needs pip install -e \".[dask]\")")
    e.add_argument("--scheduler", metavar="ADDRESS",
                   help="with --executor dask: the scheduler of a running Dask cluster, e.g. tcp://host:8786 "
                        "(default: a local cluster of --workers processes)")
    e.add_argument("--workers", type=positive_int, default=None, metavar="N",
                   help="with --executor dask and no --scheduler: worker processes of the local cluster "
                        "(default: CPU cores)")
    p.set_defaults(func=_cmd_run)

    r = subparsers.add_parser("report", help="re-render the HTML report of a run folder",
                              description="Re-render DIR/index.html from DIR/results.csv, DIR/cells and "
                                          "DIR/run.json (e.g. after an interrupted run).")
    r.add_argument("dir", metavar="DIR")
    r.add_argument("--force", action="store_true",
                   help="render even when cell files are missing or altered, or the results tables disagree with "
                        "the sealed cell records (the page lists them at the top)")
    r.add_argument("--accept-unsealed", action="store_true",
                   help="seal, once, the cell records of a folder written before seals existed (records with no "
                        "checksum are otherwise treated as altered)")
    r.set_defaults(func=_cmd_report)


def _resolve_config(args) -> RunConfig:
    if args.config:
        cfg = load_config(args.config)
    elif args.quick:
        cfg = builtin_config("quick")
    elif args.resume and args.out:
        from ..run.inputs import folder_config

        cfg = config_from_dict(folder_config(Path(args.out)), source=str(Path(args.out) / "config.json"))
    else:
        cfg = builtin_config("paper")
    if args.phantoms:
        cfg.phantoms = split_phantom_list(args.phantoms)
    if args.n:
        cfg.n = args.n
    if args.noise:
        cfg.noise = parse_noise_spec(args.noise)
    if args.degrade:
        cfg.degrade = parse_degrade_list(args.degrade)
    if args.seeds:
        if any(s < 0 for s in args.seeds):
            raise InputError("--seeds: seeds must be >= 0")
        cfg.seeds = args.seeds
    if args.imports:
        cfg.imports = list(dict.fromkeys(cfg.imports + args.imports))
    if args.method:
        cfg.methods = [parse_method_spec(s) for s in args.method]
        _drop_replaced_report_labels(cfg)
    if args.add_method:
        cfg.methods = cfg.methods + [parse_method_spec(s) for s in args.add_method]
    if args.n_samples:
        cfg.n_samples = args.n_samples
    overrides = [f"--{k.replace('_', '-')}" for k in ("phantoms", "n", "noise", "degrade", "seeds", "method",
                                                       "add_method", "imports", "n_samples") if getattr(args, k)]
    note = f"Changed on the command line ({', '.join(o.replace('--imports', '--import') for o in overrides)})."
    if any(getattr(args, k) for k in GRID_OPTIONS) and cfg.name != CUSTOM_NAME:
        # another grid is another experiment: its title and description are its own, not the config's
        cfg.description = f"{describe_grid(cfg)} Started from the {cfg.name!r} config. {note}"
        cfg.name = CUSTOM_NAME
    elif overrides and note not in cfg.description:
        cfg.description = (cfg.description + " " if cfg.description else "") + note
        if not cfg.name.endswith("*") and cfg.name != CUSTOM_NAME:
            cfg.name += "*"
    cfg.validate()
    return cfg


#: the options that change which inputs the grid has (a run with any of them is not its config's experiment)
GRID_OPTIONS = ("phantoms", "n", "noise", "degrade", "seeds")
#: the name of a run whose grid was changed on the command line
CUSTOM_NAME = "custom run"


def _listed(items: list[str], most: int = 4) -> str:
    shown = ", ".join(items[:most])
    return shown + (f", … ({len(items)} in all)" if len(items) > most else "")


def describe_grid(cfg: RunConfig) -> str:
    """One sentence saying what the grid of ``cfg`` computes: its phantoms, noise settings, degradations, N, seeds
    and method labels (the report's description of a custom run)."""
    def count(k: int, word: str) -> str:
        return f"{k} {word}{'' if k == 1 else 's'}"

    noise = [s.kind + (f"@{s.snr:g}" if isinstance(s.snr, float) else "") for s in cfg.noise]
    labels = [label for spec in cfg.methods for label, _ in spec.instances()]
    parts = [f"{count(len(cfg.phantoms), 'phantom spec')} ({_listed(cfg.phantoms)})",
             f"{count(len(noise), 'noise setting')} ({_listed(noise)})"]
    if cfg.degrade != ["none"]:
        parts.append(f"{count(len(cfg.degrade), 'input')} ({_listed(cfg.degrade)})")
    return (f"A custom run: {' × '.join(parts)} at N = {', '.join(map(str, cfg.n))}, "
            f"seed{'' if len(cfg.seeds) == 1 else 's'} {', '.join(map(str, cfg.seeds))}; "
            f"{count(len(labels), 'method')} ({_listed(labels, 8)}).")


def split_phantom_list(text: str) -> list[str]:
    """The phantoms of ``--phantoms A,B,...``: split at the commas, except that a comma inside a spec's ``?query``
    belongs to the spec (``volume:liver.nii.gz?labels=1,3,sphere`` is the labels 1 and 3, then the sphere) — a piece
    after a query that is not itself a phantom (a built-in name or a ``kind:`` spec) continues that query."""
    from phantoms import is_phantom_name

    out: list[str] = []
    for piece in (p.strip() for p in text.split(",")):
        if out and "?" in out[-1] and piece and not is_phantom_name(piece) and ":" not in piece.split("?")[0]:
            out[-1] += "," + piece
        elif piece:
            out.append(piece)
    return out


def _drop_replaced_report_labels(cfg: RunConfig) -> None:
    """The config's [report] layout names its own method labels: keep only the entries whose label --method kept."""
    labels = {label for spec in cfg.methods for label, _ in spec.instances()}
    cols = [c for c in cfg.report.get("paper_columns", []) if c["label"] in labels]
    uniform = cfg.report.get("uniform_label")
    cfg.report = {k: v for k, v in cfg.report.items() if k not in ("paper_columns", "uniform_label")}
    if cols:
        cfg.report["paper_columns"] = cols
    kept = [u for u in ([uniform] if isinstance(uniform, str) else (uniform or [])) if u in labels]
    if kept:
        cfg.report["uniform_label"] = kept[0] if isinstance(uniform, str) else kept


def _cmd_run(args) -> int:
    from ..run import RunOptions, expand_grid, run_grid
    from ..run.inputs import ExecutorSpec, check_run_inputs

    if args.resume and not args.out:
        raise InputError("--resume needs --out DIR (the folder of the run to complete)")
    cfg = _resolve_config(args)
    options = RunOptions(jobs=args.jobs, resume=args.resume, retry_failed=args.retry_failed,
                         allow_mixed_code=args.allow_mixed_code, timeout=args.timeout,
                         method_timeout=args.method_timeout, score_timeout=args.score_timeout,
                         memory_gb=args.memory_limit, save_meshes=args.save_meshes, argv=sys.argv[1:],
                         force=args.force, executor=ExecutorSpec(args.executor, args.scheduler, args.workers))
    if args.dry_run:   # nothing runs, so run_grid does not check the inputs: the same checks, no folder
        check_run_inputs(cfg, None, **options.input_checks())
        cells = expand_grid(cfg)
        for c in cells:
            print(c.cell_id)
        print(f"{len(cells)} cells ({printable(cfg.name)})")
        return 0
    out = Path(args.out) if args.out else Path("reports") / _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    preload = None if args.no_report else _preload_report()
    try:
        summary = run_grid(cfg, out, options)
    except WriteError as exc:
        raise InputError(f"{exc}; the finished cells are saved in {str(out)!r}; {_write_advice(exc)} and complete "
                         f"the run with `python -m bench run --resume --out {out}`") from None
    except KeyboardInterrupt:
        print(f"interrupted: the finished cells are in {out}; complete the run with "
              f"`python -m bench run --resume --out {out}`", file=sys.stderr)
        raise
    except Exception as exc:
        if type(exc).__name__ != "DaskRunIncomplete":
            raise
        print(f"error: {printable(exc)}; the finished cells are in {out}; complete the run with "
              f"`python -m bench run --resume --out {out} --executor dask ...`", file=sys.stderr)
        return 1
    if not args.no_report:
        preload.join()
        _report_after_run(out, summary)
    print(printable(summary.line()))
    if summary.report_error:
        print(f"warning: the report could not be written ({summary.report_error}); results are in "
              f"{out / 'results.csv'}; details in {out / 'report_error.txt'}", file=sys.stderr)
        return 1
    return 0


def _write_advice(exc: WriteError) -> str:
    """What to do about a file the run could not write, from its cause (a full disk is not a permission)."""
    import errno

    cause = str(exc.cause)
    if cause in (os.strerror(errno.ENOSPC), os.strerror(errno.EDQUOT), os.strerror(errno.EFBIG)):
        return "free space"
    if cause in (os.strerror(errno.EACCES), os.strerror(errno.EPERM), os.strerror(errno.EROFS)):
        return "fix the permissions"
    return "fix that"


def _preload_report():
    """:func:`bench.report.preload` (the report's imports, seconds) in a thread while the cells run in their own
    processes, so the report after the run does not wait for them; an import error shows when the report is
    written."""
    import threading

    # the runner imports these too (results.csv): first, here, so that the two threads never import one package
    # at the same time
    import pandas  # noqa: F401
    import pyarrow  # noqa: F401

    def load():
        try:
            from ..report import preload

            preload()
        except Exception:  # noqa: BLE001 — write_report raises it again, in its place
            pass

    t = threading.Thread(target=load, name="report-preload", daemon=True)
    t.start()
    return t


def _report_after_run(out: Path, summary) -> None:
    """Render the report into the summary; a broken report must not hide the results already on disk."""
    import traceback

    from ..report import write_report
    from ..run.values import error_text

    try:
        summary.report = write_report(out)
    except Exception as exc:
        summary.report_error = error_text(exc)
        try:
            atomic_write(out / "report_error.txt", traceback.format_exc())
        except WriteError:
            pass


def _cmd_report(args) -> int:
    from ..report import write_report

    out = Path(args.dir)
    if not (out / "results.csv").exists():
        raise InputError(f"{str(out)!r} holds no results.csv (not a run folder)")
    if not os.access(out, os.W_OK):
        raise InputError(f"{str(out)!r} is not writable")
    from ..run.audit import check_run_folder, refuse_damaged, seal_unsealed

    if args.accept_unsealed:
        sealed, refused = seal_unsealed(out)
        print(f"sealed {len(sealed)} cell record(s) written before seals (--accept-unsealed)"
              + (f"; left {len(refused)} unsealed that disagree with the results tables" if refused else ""),
              file=sys.stderr)
    problems = check_run_folder(out)    # records and tables (a malformed results.csv: exit 2 with its line)
    if not args.force:
        refuse_damaged(out, problems, ", or render anyway with --force", sealing_tried=args.accept_unsealed)
    path = write_report(out, problems=problems)
    if problems:
        print(printable(f"warning: {len(problems)} problem(s) against the sealed cell records, listed at the top "
                        "of the page"), file=sys.stderr)
    print(f"wrote {path}")
    return 0
