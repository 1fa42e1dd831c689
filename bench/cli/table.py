"""``python -m bench table RUN --format markdown|latex|csv [--metric M,...] [--by phantom,noise] [-o FILE]``:
a run's summary tables for a paper or a README.

The tables are :mod:`bench.report.export`'s; this room parses the arguments and writes the text (stdout, or
``-o FILE`` atomically); exit 2 on bad input (not a run folder, an unknown metric or grouping, a results table
that disagrees with the sealed cell records or a record or ``.npz`` altered: :mod:`bench.run.audit`).
"""

from __future__ import annotations

from pathlib import Path

from geometry.errors import InputError
from geometry.files import atomic_write, check_writable

from ..terminal import printable

HELP = """\
Print the run's summary tables: one per group of cells (default: phantom x noise, and variant / N when the run
varies them), methods as rows, metrics as columns, each value the mean over the group's ok cells (its seeds);
`cells` = ok cells / cells. The best value of a column is bold where it is unique. markdown: GitHub pipe tables;
latex: booktabs tables (\\usepackage{booktabs}), units in the header; csv: the means at full precision.
--recommend: the report's first section, which method to use per shape kind x input, each cell one verdict of
the pairwise tests with what it rests on (csv: one line per cell)."""


def _names(values) -> list[str] | None:
    if not values:
        return None
    return [x.strip() for v in values for x in v.split(",") if x.strip()]


def register(subparsers) -> None:
    from ..report.export import DEFAULT_METRICS, FORMATS, GROUP_KEYS

    p = subparsers.add_parser("table", help="a run's summary tables as markdown, LaTeX or CSV", description=HELP)
    p.add_argument("run", metavar="RUN", help="a run folder")
    p.add_argument("--format", choices=FORMATS, default="markdown", help="output format (default markdown)")
    p.add_argument("--metric", action="append", metavar="M[,M...]",
                   help=f"metric columns (repeatable; default: {', '.join(DEFAULT_METRICS)}, those the run has; "
                        "without ground truth: the data-fidelity metrics)")
    p.add_argument("--by", metavar="K[,K...]",
                   help=f"one table per value of these ({', '.join(GROUP_KEYS)}; default phantom,noise)")
    p.add_argument("--leaderboard", action="store_true",
                   help="the leaderboards instead (mean rank per key metric, wins / ties / losses, each board's "
                        "verdict), after the recommendation table in markdown")
    p.add_argument("--recommend", action="store_true",
                   help="only the recommendation per shape kind x input (the report's first section)")
    p.add_argument("-o", "--output", metavar="FILE", help="write to FILE instead of stdout")
    p.set_defaults(func=_cmd_table)


def _cmd_table(args) -> int:
    from ..report.export import group_tables, leaderboard_tables, to_csv, to_latex, to_markdown
    from ..report.tables import complete_inputs
    from ..run.results import read_results

    if args.output:
        check_writable(args.output)
    from ..run.audit import check_run_folder, refuse_damaged

    by = _names([args.by]) if args.by is not None else None
    refuse_damaged(args.run, check_run_folder(args.run))   # the sealed records (and their arrays) are the truth
    df = read_results(Path(args.run))
    if args.recommend or args.leaderboard:
        from ..report import recommend as rec

        if not len(df):
            raise InputError("the run has no finished cells: no recommendation to make")
        table = rec.recommendation_table(complete_inputs(df).to_dict("records"))
        first = {"markdown": rec.recommendation_markdown, "latex": rec.recommendation_latex,
                 "csv": rec.recommendation_csv}[args.format](table)
    if args.recommend:
        text = first
    else:
        tables = leaderboard_tables(df) if args.leaderboard else group_tables(df, metrics=_names(args.metric), by=by)
        text = {"markdown": to_markdown, "latex": to_latex, "csv": to_csv}[args.format](tables)
        if args.leaderboard and args.format == "markdown":
            text = first + "\n" + text
    # names a user or a plug-in chose (a phantom's file, a method label) reach the terminal or file escaped
    text = printable(text)
    if args.output:
        print(printable(f"wrote {atomic_write(args.output, text)}"))
    else:
        print(text, end="")
    return 0
