"""``python -m bench perf``: run the benchmark suites, print median / ratio / change, gate against a baseline."""

from __future__ import annotations

import argparse
import datetime as _dt
import sys

from .. import perf
from .validators import int_at_least, nonneg_float

PERF_HELP = """\
Run the pytest-benchmark suites (tests/benchmarks) and print each benchmark's median time and its ratio to
the same-session reference (marching cubes on the ellipsoid at N = 96). With --compare, also the change of
each ratio against the baseline; exit code 1 when a ratio is worse than the baseline by more than
--tolerance (or when a benchmark fails), 0 otherwise, 2 on bad input.

Benchmarks over the tolerance are rerun (--retries) and keep their best ratio: a real regression is slow
every time, a load spike on a shared machine rarely hits the same benchmark twice.

Typical uses:
  python -m bench perf --compare bench/perf/baseline.json            # check this tree
  python -m bench perf --quick --compare bench/perf/baseline.json    # CI: fewer rounds, slow ones skipped
  python -m bench perf --repeat 5 --save bench/perf/baseline.json    # refresh the baseline (quiet machine)

Quality (--quality / --save-quality): the quick grid and a bunny cell are run and each cell's metrics compared
with the committed bench/perf/quality.json (bench/metrics/tolerances.py: tolerances per metric); a worse value, a
worse status or a new flag fails. History (--history FILE.jsonl): each run appended as a JSON line;
--plot FILE.jsonl -o history.html draws it.
  python -m bench perf --quick --compare bench/perf/baseline.json --quality bench/perf/quality.json   # CI
  python -m bench perf --no-timing --save-quality bench/perf/quality.json     # refresh the quality baseline
  python -m bench perf --quick --compare bench/perf/baseline.json --history perf-history.jsonl
  python -m bench perf --plot perf-history.jsonl -o perf-history.html"""


def register(subparsers) -> None:
    p = subparsers.add_parser("perf", help="run the performance suites and gate against a baseline",
                              description=PERF_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--compare", metavar="BASELINE.json",
                   help="baseline to compare with (a perf summary or a pytest-benchmark JSON file)")
    p.add_argument("--save", metavar="OUT.json", help="write this run's summary (e.g. a new baseline)")
    p.add_argument("--tolerance", type=nonneg_float, default=perf.DEFAULT_TOLERANCE, metavar="T",
                   help="fail when ratio > baseline ratio × (1 + T) (default 0.5, i.e. 50 %% slower)")
    p.add_argument("--quick", action="store_true",
                   help="short mode: fewer rounds, benchmarks marked perf_slow skipped (CI)")
    p.add_argument("--repeat", type=int_at_least(1), default=1, metavar="K",
                   help="run the suite K times and keep per benchmark the median ratio (for baselines)")
    p.add_argument("--retries", type=int_at_least(0), default=1, metavar="R",
                   help="rerun the benchmarks over the tolerance up to R times, keeping their best ratio "
                        "(default 1; 0 = none)")
    p.add_argument("--rounds", type=int_at_least(1), default=None, metavar="N",
                   help="force N rounds for every benchmark (default: each benchmark's own for the mode)")
    p.add_argument("--metric", choices=("cpu", "wall"), default="cpu",
                   help="ratio the gate compares: CPU time (default; robust to other load on the machine) or "
                        "wall-clock time")
    p.add_argument("--cpus", type=int_at_least(0), default=1, metavar="C",
                   help="pin the suite to C CPUs (default 1: a multi-threaded benchmark's ratio then does not "
                        "depend on how many cores are free; 0 = no pinning)")
    p.add_argument("-k", dest="keyword", metavar="EXPR", help="only the benchmarks matching this pytest -k "
                                                              "expression")
    p.add_argument("--input", metavar="RUN.json", action="append", default=None,
                   help="use measurements already made (perf summaries or pytest-benchmark JSON files; "
                        "repeatable, merged like --repeat) instead of running the suite")
    p.add_argument("--fail-on-missing", action="store_true",
                   help="also fail when a baseline benchmark did not run (not counting --quick skips)")
    q = p.add_argument_group("quality gate and history")
    q.add_argument("--quality", metavar="QUALITY.json",
                   help="also run the quality grids (quick + quality_real) and fail when a cell's metric is worse "
                        "than in this baseline beyond its tolerance, or its status / flags got worse")
    q.add_argument("--save-quality", metavar="OUT.json", help="also run the quality grids and save their values "
                                                              "(e.g. a new quality baseline)")
    q.add_argument("--no-timing", action="store_true", help="skip the benchmark suites (quality only)")
    q.add_argument("--history", metavar="FILE.jsonl",
                   help="append this run (commit, date, machine, load, ratios, quality, verdicts) as a JSON line")
    q.add_argument("--plot", metavar="FILE.jsonl", help="draw the history FILE (every ratio and quality metric "
                                                        "across runs) into -o and exit")
    q.add_argument("-o", "--plot-out", metavar="OUT.html", default="perf-history.html",
                   help="the page --plot writes (default perf-history.html)")
    p.set_defaults(func=_cmd_perf)


def _run(args, select=None, keyword=None) -> tuple[int, dict | None]:
    return perf.run_suite(quick=args.quick, select=select, keyword=keyword, n_rounds=args.rounds,
                          cpus=args.cpus)


def _timing(args, baseline) -> tuple[int, dict, object, dict]:
    """Run (or read) the suites, gate them, rerun the benchmarks over the tolerance: (code, current, result,
    retried)."""
    if args.input:
        runs = [perf.load_summary(p) for p in args.input]
        code = 0
    else:
        runs, code = [], 0
        for i in range(args.repeat):
            if args.repeat > 1:
                print(f"perf: suite run {i + 1}/{args.repeat}", file=sys.stderr)
            rc, summary = _run(args, keyword=args.keyword)
            if rc != 0:
                print(f"perf: the benchmark suite exited with code {rc}", file=sys.stderr)
                code = 1
            if summary is None:
                print("perf: no benchmark results (see the pytest output above)", file=sys.stderr)
                return 1, {}, None, {}
            runs.append(summary)
    current = perf.merge_runs(runs)
    result = perf.gate(baseline, current, args.tolerance, fail_on_missing=args.fail_on_missing,
                       metric=args.metric)
    retried: dict[str, list] = {}
    for attempt in range(args.retries if (baseline is not None and not args.input) else 0):
        bad = [r["name"] for r in result.rows if r["status"] == perf.REGRESSION]
        ids = [i for i in (current["benchmarks"][n].get("fullname") for n in bad) if i]
        if not ids:
            break
        print(f"perf: {len(bad)} benchmark(s) over the tolerance, rerun {attempt + 1}/{args.retries}: "
              f"{', '.join(bad)}", file=sys.stderr)
        rc, again = _run(args, select=ids)
        if again is None:
            break
        gated = {r["name"]: ("cpu_ratio" if r["metric"] == "cpu" else "ratio") for r in result.rows}
        for n in bad:
            new, old, key = again["benchmarks"].get(n), current["benchmarks"][n], gated[n]
            if new is None or new.get(key) is None:
                continue
            retried.setdefault(n, [old.get(key)]).append(new[key])
            if old.get(key) is None or new[key] < old[key]:
                current["benchmarks"][n] = dict(new, attempts=retried[n])
            else:
                old["attempts"] = retried[n]
        result = perf.gate(baseline, current, args.tolerance, fail_on_missing=args.fail_on_missing,
                           metric=args.metric)
    return code, current, result, retried


def _print_timing(args, baseline, current, result, retried) -> None:
    ref = current.get("reference") or {}
    load = current.get("loadavg") or {}
    print(f"reference (marching cubes, ellipsoid N = 96): median {perf.format_seconds(ref.get('median_s'))}; "
          f"mode {current.get('mode') or '?'}; load average {load}")
    print(perf.format_table(result))
    if baseline is None:
        return
    print(f"baseline: {args.compare} ({baseline.get('created', '?')}, mode {baseline.get('mode', '?')}); "
          f"gate: {args.metric} ratio, tolerance {100 * args.tolerance:g} %"
          + ("; * = wall-clock ratio (no CPU ratio on both sides)" if any(
              r["metric"] == "wall" and r["change"] is not None for r in result.rows) else ""))
    what = {perf.MISSING: "in the baseline, not in this run",
            perf.NEW: "new: not in the baseline (refresh it to gate this one)",
            perf.SKIPPED: "skipped in this mode",
            perf.FASTER: "faster than the baseline beyond the tolerance: refresh the baseline"}
    for r in result.rows:
        if r["status"] in what:
            print(f"  {r['name']}: {what[r['status']]}")
    if n := len(retried):
        print(f"  rerun: {n} benchmark(s) — ratios per attempt: "
              + "; ".join(f"{k} {[round(x, 3) for x in v if x is not None]}" for k, v in retried.items()))


def _timing_failure(args, result) -> str:
    status = {r["name"]: r["status"] for r in result.rows}
    slow = [n for n in result.failures if status[n] == perf.REGRESSION]
    gone = [n for n in result.failures if status[n] != perf.REGRESSION]
    return "; ".join(([f"{', '.join(slow)} slower than the baseline by more than {100 * args.tolerance:g} %"]
                      if slow else []) + ([f"{', '.join(gone)} did not run"] if gone else []))


def _quality(args):
    """Run the quality grids when asked; (summary or None, result or None)."""
    from ..perf import quality as q

    if not (args.quality or args.save_quality):
        return None, None
    baseline = q.load_quality(args.quality) if args.quality else None   # bad file: fail before running
    print("perf: running the quality grids (" + ", ".join(q.QUALITY_CONFIGS) + ")", file=sys.stderr)
    current = q.run_quality()
    result = None
    if baseline is not None:
        result = q.quality_gate(baseline, current)
        print(q.format_quality(result))
        print(f"quality baseline: {args.quality} ({baseline.get('created', '?')}, commit "
              f"{(baseline.get('commit') or {}).get('commit', '?')})")
        exact = ("bit for bit (same machine and libraries as the baseline)"
                 if baseline.get("machine") == current.get("machine")
                 else f"within {q.EXACT_REL_ELSEWHERE:g} relative (another machine or other library versions)")
        print(f"quality: {', '.join(q.EXACT_METHODS)} rows compared {exact}")
    if args.save_quality:
        print(f"wrote {q.save_quality(current, args.save_quality)}")
    return current, result


def _cmd_perf(args) -> int:
    from ..perf import history as h

    if args.plot:
        print(f"wrote {h.plot_history(args.plot, args.plot_out)}")
        return 0
    baseline = perf.load_summary(args.compare) if args.compare else None
    code, current, result, failures = 0, None, None, []
    if not args.no_timing:
        code, current, result, retried = _timing(args, baseline)
        if result is None:
            return 1
        _print_timing(args, baseline, current, result, retried)
        if args.save:
            note = {"saved": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
                    "argv": sys.argv[1:], **perf.machine_note()}
            print(f"wrote {perf.save_summary(current, args.save, note)}")
        if not result.passed:
            print(f"perf: FAILED — {_timing_failure(args, result)}", file=sys.stderr)
            failures += result.failures
            code = 1
    quality, qresult = _quality(args)
    if qresult is not None and not qresult.passed:
        bad = sorted({f"{r['cell']} {r['metric']}" for r in qresult.failures})
        print(f"perf: quality FAILED — {len(bad)} value(s) worse than the baseline (exact rows: changed): "
              + "; ".join(bad[:8])
              + (" …" if len(bad) > 8 else ""), file=sys.stderr)
        failures += bad
        code = 1
    if args.history:
        entry = h.history_entry(current, quality,
                                timing_passed=None if result is None or baseline is None else result.passed,
                                quality_passed=None if qresult is None else qresult.passed, failures=failures)
        print(f"appended to {h.append_history(args.history, entry)}")
    if code == 0 and (baseline is not None or qresult is not None):
        print("perf: passed")
    return code
