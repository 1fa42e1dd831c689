"""The reliability battery: the suite's command line run as a hostile user and a careless plug-in would.

Each case writes its own fixtures (volumes in every format, run folders edited or killed, plug-ins that
misbehave, configs at the limits) in a temporary folder, runs ``python -m bench ...`` (info, reconstruct, run,
run --resume, report, table, compare, methods, check-method) and checks what the suite promises: exit code 2 and
one line naming the problem (no traceback), a failed row with its reason, or a results table refused or repaired.
Cases are grouped by the cause of the reliability issue they test; the script prints one line per failed case,
then per cause the cases and how many passed.  It is not part of pytest: it takes minutes, on purpose end to end::

    python docs/scripts/battery.py                  # every case, 2 at a time
    python docs/scripts/battery.py --cause 3 --cause 7 --keep

Exit 0 when every case passed, 1 otherwise.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import time
import traceback
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from battery import files, images, inputs, plugins, runs, tables, truth
from battery.core import Case, Ctx

CAUSES = {
    "1": "results.csv / results.parquet edited: report, table, compare",
    "2": "sealed cell records edited or planted",
    "3": "oblique and sheared images",
    "4": "DICOM series with a gap",
    "5": "the volume handed to a method is read-only",
    "6": "a plug-in module that exits at import",
    "7": "non-finite numbers where an integer is expected",
    "8": "TOML nested thousands of levels",
    "9": "headers claiming more than the file or the memory",
    "10": "grids too large to expand",
    "11": "failing plug-ins in reconstruct, check-method and run",
    "12": "FIFOs, devices and folders that never end or open",
    "13": "terminal controls in plug-in text and file names",
    "14": "command-line errors: one line, no usage block",
    "15": "library text and unreadable files",
    "16": "options silently ignored or coerced",
    "17": "a truth in the wrong coordinates",
    "resume": "kill-and-resume equals an uninterrupted run",
}


def all_cases() -> list[Case]:
    """Every case of the battery, in the order of the causes."""
    cases = (tables.cases() + images.oblique_cases() + images.dicom_cases() + plugins.cases()
             + inputs.cases() + files.size_cases() + files.hang_cases() + files.unreadable_cases()
             + truth.cases() + runs.cases())
    order = list(CAUSES)
    return sorted(cases, key=lambda c: order.index(c.cause))


def run_case(ctx: Ctx, case: Case) -> str | None:
    """The case's reason for failing (an exception of the battery itself is one too), or None."""
    try:
        return case.check(ctx)
    except Exception as exc:  # noqa: BLE001 — a broken fixture is a failed case, reported, not the end of the battery
        return f"battery error: {type(exc).__name__}: {exc} ({traceback.format_exc(limit=-1).splitlines()[-3]})"


def main(argv: list[str] | None = None) -> int:
    """Run the selected cases and print the failures and the tally; exit 0 when all passed."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cause", action="append", help="only this cause (repeatable; 1-17 or 'resume')")
    ap.add_argument("--match", help="only cases whose name contains this text")
    ap.add_argument("--jobs", type=int, default=2, help="cases run at once (default 2)")
    ap.add_argument("--keep", action="store_true", help="keep the fixture folder and print its path")
    args = ap.parse_args(argv)
    cases = [c for c in all_cases() if (not args.cause or c.cause in args.cause)
             and (not args.match or args.match in c.name)]
    root = Path(tempfile.mkdtemp(prefix="lsb-battery-"))
    ctx = Ctx(root)
    start = time.monotonic()
    try:
        with ThreadPoolExecutor(max(1, args.jobs)) as pool:
            reasons = list(pool.map(lambda c: run_case(ctx, c), cases))
    finally:
        if args.keep:
            print(f"fixtures kept in {root}")
        else:
            shutil.rmtree(root, ignore_errors=True)
    total, passed = Counter(), Counter()
    for case, reason in zip(cases, reasons):
        total[case.cause] += 1
        if reason is None:
            passed[case.cause] += 1
        else:
            print(f"FAIL [{case.cause}] {case.name}: {reason}".replace("\n", " "))
    print(f"\n{'cause':>6}  {'cases':>5}  {'passed':>6}  what")
    for cause, what in CAUSES.items():
        if total[cause]:
            print(f"{cause:>6}  {total[cause]:>5}  {passed[cause]:>6}  {what}")
    n, ok = sum(total.values()), sum(passed.values())
    print(f"{'all':>6}  {n:>5}  {ok:>6}  in {time.monotonic() - start:.0f} s")
    return 0 if ok == n else 1


if __name__ == "__main__":
    sys.exit(main())
