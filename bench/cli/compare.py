"""``python -m bench compare RUN_A RUN_B [--fail-on-worse] [--html OUT.html]``: what changed from run A to run B.

The matching and the verdicts are :mod:`bench.report.compare`'s; this room parses the arguments, prints, writes
the page and picks the exit code: 0, or 1 with ``--fail-on-worse`` when something got worse; 2 on bad input
(a folder that is not a run, or whose results tables disagree with its sealed cell records, or a record or
``.npz`` altered: :mod:`bench.run.audit`) and when no cell of the two runs matched (one line saying why and how to
pair the labels).
"""

from __future__ import annotations

from pathlib import Path

from geometry.files import atomic_write, check_writable
from phantoms import InputError

from ..terminal import printable

HELP = """\
Compare two run folders cell by cell (before / after a change to a method). Cells are matched on phantom,
variant, N, noise, SNR, seed and method label (not on the cell id: a changed parameter changes it); each metric
of the quality gate is judged better / worse / same with the gate's tolerances (`bench perf --quality`).
Concludes per method and key metric over the inputs both runs share (seeds, shapes): the median change with a
95 % interval and a paired Wilcoxon signed-rank test, Holm-corrected ("significantly worse", "no significant
change", ...). Then lists the changed methods and parameters, the worse and better values per cell, the cells
whose status or flags changed, the cells found in one run only, and a summary line ("no change" when nothing
did)."""


def register(subparsers) -> None:
    p = subparsers.add_parser("compare", help="compare two run folders cell by cell", description=HELP)
    p.add_argument("run_a", metavar="RUN_A", help="the run before (a run folder)")
    p.add_argument("run_b", metavar="RUN_B", help="the run after")
    p.add_argument("--fail-on-worse", action="store_true",
                   help="exit 1 on a significant worsening of a key metric, a worse status or a gained flag "
                        "(a method with fewer than 6 shared inputs: any value beyond its tolerance) (CI)")
    p.add_argument("--html", metavar="OUT.html", help="also write the comparison as a self-contained page")
    p.set_defaults(func=_cmd_compare)


def _cmd_compare(args) -> int:
    from ..report.compare import compare_runs, comparison_html, format_comparison

    from ..run.audit import check_run_folder, refuse_damaged

    if args.html:
        check_writable(args.html)
    for run in (args.run_a, args.run_b):      # the sealed records are the truth: a table that departs is refused
        refuse_damaged(run, check_run_folder(run))
    cmp = compare_runs(Path(args.run_a), Path(args.run_b))
    if not cmp.matched:             # nothing to compare is not "no change"
        raise InputError(printable(f"compare: 0 cells matched: {cmp.unmatched_reason}"))
    print(printable(format_comparison(cmp)))
    if args.html:
        path = atomic_write(args.html, comparison_html(cmp))
        print(printable(f"wrote {path}"))
    return 1 if args.fail_on_worse and cmp.worse else 0
