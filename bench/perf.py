"""Performance tracking: run the pytest-benchmark suites, compare their ratios with a baseline, gate regressions.

``python -m bench perf [--compare BASELINE.json] [--save OUT.json] [--tolerance 0.5] [--quick]`` (see
:mod:`bench.cli_perf`) runs ``tests/benchmarks`` (pytest with ``--benchmark-json`` into a temporary file),
prints a table and, with ``--compare``, exits 1 when a benchmark got slower than the baseline by more than the
tolerance.

Why ratios, and why CPU time
----------------------------
Absolute times depend on the machine and on its load.  Every benchmark records in ``extra_info`` its median
time divided by the median time of a *reference* measured in the same pytest session (marching cubes on the
ellipsoid at N = 96; ``tests/benchmarks/conftest.py``): ``ratio`` with wall-clock times and ``cpu_ratio`` with
CPU times (user + system of the process, its threads and its worker processes: :func:`process_tree_cpu`).  A
faster machine changes the benchmark and the reference alike; the ratio moves when the benchmarked code itself
changes speed.  The reference rounds a benchmark is divided by are the ones timed around it (before, between its
rounds, after): the speed of a shared virtual machine drifts over tens of seconds.

Wall-clock ratios are not enough on a shared machine: other processes slow a 15-second benchmark and a
0.1-second reference round by different amounts depending on when they run.  On this project's 2-core machine
with 3–6 busy processes of other jobs, the wall-clock ratio of the same code moved by up to 85 % between two
runs.  CPU time is charged only while the process runs, so the CPU-time ratio moves much less under such load
(what remains comes from the virtual machine's host: the same code's CPU time drifts by ±20 %); the gate compares ``cpu_ratio`` (``--metric cpu``, the default) and falls back to ``ratio`` for a benchmark without
CPU times on both sides.  What CPU time cannot see — time spent waiting — is in the wall-clock column, for
information (``--metric wall`` gates on it).  The suite runs pinned to one CPU (:func:`run_suite` ``cpus``), with
the native thread pools at one thread, so a benchmark's cost does not depend on how many cores are free: the
suite measures work, not parallel speed-up.

The gate (:func:`gate`, a pure function)
---------------------------------------
``change = ratio / baseline_ratio − 1``; a benchmark **fails** when ``change > tolerance`` (default 0.5: more
than 50 % slower relative to the reference).  Benchmarks only in the run are ``new`` and benchmarks only in the
baseline are ``missing`` (or ``skipped`` when the run said so, e.g. ``--quick``); neither fails unless
``fail_on_missing``.  A benchmark without a ratio (e.g. run with ``--benchmark-disable``) is ``no ratio``.
Faster than the baseline by the same factor (``ratio < baseline / (1 + tolerance)``) is ``faster`` — time to
refresh the baseline so the gate keeps its sensitivity.

Summary files
-------------
``--save`` writes, and ``--compare`` reads, a small JSON (``"format": "levelset-bench-perf/1"``): per benchmark
the median/min/max seconds, rounds and ratio, plus the reference, the load averages and the machine.  ``--compare``
and ``--input`` also accept a raw ``--benchmark-json`` file of pytest-benchmark.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from phantoms import InputError

__all__ = ["perf_mode", "rounds", "DEFAULT_TOLERANCE", "FORMAT", "summarise", "load_summary", "merge_runs",
           "gate", "GateResult", "format_table", "run_suite", "benchmarks_dir"]

FORMAT = "levelset-bench-perf/1"
DEFAULT_TOLERANCE = 0.5
ENV_MODE = "LSB_PERF_MODE"
ENV_ROUNDS = "LSB_PERF_ROUNDS"
#: native thread pools pinned to one thread in the suite's process (unless already set): the reference is
#: single-threaded, so a benchmark's ratio must not depend on how many cores happen to be free
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")

#: statuses of :func:`gate` rows
OK, FASTER, REGRESSION, NEW, MISSING, SKIPPED, NO_RATIO = ("ok", "faster", "REGRESSION", "new", "missing",
                                                          "skipped", "no ratio")


# ---------------------------------------------------------------------------------------------- suite modes
def perf_mode() -> str:
    """``"quick"`` or ``"full"`` (environment ``LSB_PERF_MODE``; default full)."""
    mode = os.environ.get(ENV_MODE, "full").strip().lower()
    return "quick" if mode == "quick" else "full"


def rounds(full: int, quick: int) -> int:
    """Rounds a benchmark runs in the current mode (``LSB_PERF_ROUNDS`` overrides both)."""
    forced = os.environ.get(ENV_ROUNDS, "").strip()
    if forced:
        return max(1, int(forced))
    return quick if perf_mode() == "quick" else full


# ---------------------------------------------------------------------------------------------- CPU time
_CLK = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _children_of(pid: int) -> list[int]:
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return []
    out: list[int] = []
    for t in tasks:
        try:
            with open(f"/proc/{pid}/task/{t}/children") as fh:
                out += [int(x) for x in fh.read().split()]
        except (OSError, ValueError):
            continue
    return out


def _descendants_cpu() -> float:
    """CPU seconds (user + system, own + reaped children) of the live descendants of this process (Linux
    ``/proc``; 0 elsewhere).  A descendant that is reaped later moves its time into its parent's children
    time, which is counted too: nothing is lost or counted twice between two readings."""
    total = 0.0
    todo, seen = _children_of(os.getpid()), set()
    while todo:
        pid = todo.pop()
        if pid in seen:
            continue
        seen.add(pid)
        try:
            with open(f"/proc/{pid}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            total += sum(int(x) for x in fields[11:15]) / _CLK   # utime stime cutime cstime
        except (OSError, ValueError, IndexError):
            continue
        todo += _children_of(pid)
    return total


def _own_cpu() -> float:
    import resource

    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def process_tree_cpu(*, self_last: bool = True) -> float:
    """CPU seconds used so far by this process, its threads and every descendant process (the worker processes
    of the grid runner, forked from a fork server, included).  ``self_last``: read this process's own time
    after scanning ``/proc`` (use at the start of a measured interval, and ``self_last=False`` at its end, so
    the scan's own CPU falls outside the interval)."""
    if self_last:
        d = _descendants_cpu()
        return d + _own_cpu()
    own = _own_cpu()
    return own + _descendants_cpu()


class CpuRecordingTimer:
    """A pytest-benchmark timer: returns ``time.perf_counter()`` (the statistics stay wall-clock) and records
    the CPU time of the process tree over each timed interval in :attr:`cpu` (one entry per timed call,
    warm-up rounds included; the calls alternate start, end).  ``before``: called at each start, before the
    clocks are read (outside the timed interval) — the benchmarks time a reference round there."""

    __name__ = "perf_counter+cpu"

    def __init__(self, before=None) -> None:
        import time

        self._clock = time.perf_counter
        self._before = before
        self._start: float | None = None
        self.cpu: list[float] = []

    def __call__(self) -> float:
        if self._start is None:
            if self._before is not None:
                self._before()
            self._start = process_tree_cpu(self_last=True)
            return self._clock()
        t = self._clock()
        self.cpu.append(process_tree_cpu(self_last=False) - self._start)
        self._start = None
        return t


# ---------------------------------------------------------------------------------------------- summaries
def _finite(x) -> float | None:
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def summarise(raw: dict) -> dict:
    """The summary of a pytest-benchmark ``--benchmark-json`` document (a summary is returned unchanged)."""
    if raw.get("format") == FORMAT:
        return raw
    if "benchmarks" not in raw or not isinstance(raw["benchmarks"], list):
        raise InputError("not a pytest-benchmark JSON file nor a levelset-bench perf summary")
    names = [b.get("name") for b in raw["benchmarks"]]
    benches: dict[str, dict] = {}
    for b in raw["benchmarks"]:
        st = b.get("stats") or {}
        extra = b.get("extra_info") or {}
        key = b["name"] if names.count(b["name"]) == 1 else b.get("fullname", b["name"])
        benches[key] = {
            "group": b.get("group"),
            "fullname": b.get("fullname"),
            "median_s": _finite(st.get("median")),
            "min_s": _finite(st.get("min")),
            "max_s": _finite(st.get("max")),
            "iqr_s": _finite(st.get("iqr")),
            "rounds": st.get("rounds"),
            "ratio": _finite(extra.get("ratio")),
            "cpu_mean_s": _finite(extra.get("cpu_mean_s")),
            "cpu_ratio": _finite(extra.get("cpu_ratio")),
            "loadavg_1min": extra.get("loadavg_1min"),
        }
    lb = raw.get("levelset_bench") or {}
    mi = raw.get("machine_info") or {}
    cpu = mi.get("cpu") or {}
    commit = raw.get("commit_info") or {}
    return {
        "format": FORMAT,
        "created": raw.get("datetime") or _dt.datetime.now(_dt.timezone.utc).isoformat(),
        "mode": lb.get("mode"),
        "machine": {"node": mi.get("node"), "cpu": cpu.get("brand_raw") or mi.get("processor"),
                    "cpu_count": lb.get("cpu_count") or cpu.get("count"), "system": mi.get("system"),
                    "python": mi.get("python_version")},
        "commit": {"id": commit.get("id"), "dirty": commit.get("dirty")},
        "loadavg": {"start": lb.get("loadavg_start"), "end": lb.get("loadavg_end")},
        "reference": lb.get("reference"),
        "skipped": sorted(lb.get("skipped") or []),
        "benchmarks": dict(sorted(benches.items())),
    }


def load_summary(path: str | Path) -> dict:
    """Read a perf summary or a raw pytest-benchmark JSON file (:class:`InputError` if unreadable)."""
    p = Path(path)
    try:
        raw = json.loads(p.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read {str(p)!r}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise InputError(f"{str(p)!r} is not JSON: {exc}") from None
    if not isinstance(raw, dict):
        raise InputError(f"{str(p)!r}: not a perf summary")
    try:
        return summarise(raw)
    except InputError as exc:
        raise InputError(f"{str(p)!r}: {exc}") from None


def _median(values: Iterable) -> float | None:
    v = [x for x in values if x is not None]
    return statistics.median(v) if v else None


def merge_runs(runs: list[dict]) -> dict:
    """Several summaries of the same suite → one: per benchmark the median over runs of the median time and of
    each ratio (``runs`` keeps every run's values).  Summaries that are themselves merges count with each of
    their runs.  Metadata of the first summary; every run's load averages and reference."""
    if not runs:
        raise ValueError("no runs to merge")
    if len(runs) == 1:
        return runs[0]
    keys = ("median_s", "ratio", "cpu_mean_s", "cpu_ratio")

    def values(b: dict, k: str) -> list:
        return list(b["runs"][k]) if isinstance(b.get("runs"), dict) and k in b["runs"] else [b.get(k)]

    out = json.loads(json.dumps(runs[0]))
    names = sorted({n for r in runs for n in r["benchmarks"]})
    benches = {}
    for n in names:
        rows = [r["benchmarks"][n] for r in runs if n in r["benchmarks"]]
        b = {k: v for k, v in rows[0].items() if k not in ("runs", "attempts")}
        allv = {k: [x for r in rows for x in values(r, k)] for k in keys}
        for k in keys:
            b[k] = _median(allv[k])
        b["min_s"] = min((r["min_s"] for r in rows if r.get("min_s") is not None), default=None)
        b["max_s"] = max((r["max_s"] for r in rows if r.get("max_s") is not None), default=None)
        b["rounds"] = sum(int(r.get("rounds") or 0) for r in rows)
        b["runs"] = allv
        benches[n] = b
    out["benchmarks"] = benches

    def each(r: dict, key: str) -> list:
        v = r.get(key) or {}
        return list(v["runs"]) if isinstance(v, dict) and "runs" in v else [v]

    out["loadavg"] = {"runs": [x for r in runs for x in each(r, "loadavg")]}
    refs = [x for r in runs for x in each(r, "reference")]
    out["reference"] = {k: _median((x or {}).get(k) for x in refs) for k in ("median_s", "cpu_mean_s")}
    out["reference"]["runs"] = refs
    out["skipped"] = sorted(set.intersection(*(set(r.get("skipped") or []) for r in runs)))
    out["repeats"] = sum(int(r.get("repeats") or 1) for r in runs)
    return out


# ---------------------------------------------------------------------------------------------- the gate
@dataclass
class GateResult:
    """Rows (one per benchmark, sorted by name) and the verdict of :func:`gate`."""

    rows: list[dict] = field(default_factory=list)
    tolerance: float = DEFAULT_TOLERANCE
    compared: bool = True

    @property
    def failures(self) -> list[str]:
        return [r["name"] for r in self.rows if r["failed"]]

    @property
    def passed(self) -> bool:
        return not self.failures


def _bench_map(summary: dict | None) -> dict[str, dict]:
    if summary is None:
        return {}
    b = summary.get("benchmarks", summary)
    # allow the plain form {name: ratio}
    return {k: (v if isinstance(v, dict) else {"ratio": v}) for k, v in b.items()}


def gate(baseline: dict | None, current: dict, tolerance: float = DEFAULT_TOLERANCE, *,
         fail_on_missing: bool = False, metric: str = "cpu") -> GateResult:
    """Compare the ratios of ``current`` with those of ``baseline`` (summaries, or plain ``{name: ratio}``).

    ``metric``: ``"cpu"`` compares the CPU-time ratios (``cpu_ratio``) of the benchmarks that have one on both
    sides and the wall-clock ratios of the others; ``"wall"`` always the wall-clock ratios (``ratio``).
    Pure: no I/O.  ``baseline=None`` gives the rows without a verdict (every row passes).  See the module
    docstring for the statuses.
    """
    if not (tolerance >= 0 and math.isfinite(tolerance)):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    if metric not in ("cpu", "wall"):
        raise ValueError(f"metric must be 'cpu' or 'wall', got {metric!r}")
    base, cur = _bench_map(baseline), _bench_map(current)
    skipped = set((current or {}).get("skipped") or []) if isinstance(current, dict) else set()
    rows = []
    for name in sorted(set(base) | set(cur)):
        b, c = base.get(name), cur.get(name)
        key = "ratio"
        if metric == "cpu" and (c is None or _finite(c.get("cpu_ratio")) is not None) \
                and (b is None or _finite(b.get("cpu_ratio")) is not None):
            key = "cpu_ratio"
        row = {"name": name, "median_s": (c or {}).get("median_s"), "wall_ratio": _finite((c or {}).get("ratio")),
               "cpu_ratio": _finite((c or {}).get("cpu_ratio")), "metric": "cpu" if key == "cpu_ratio" else "wall",
               "ratio": _finite((c or {}).get(key)), "baseline_ratio": _finite((b or {}).get(key)),
               "baseline_median_s": (b or {}).get("median_s"), "change": None, "failed": False}
        if c is None:
            row["status"] = SKIPPED if name in skipped else MISSING
            row["failed"] = fail_on_missing and baseline is not None and name not in skipped
        elif baseline is None:
            row["status"] = OK if row["ratio"] is not None else NO_RATIO
        elif b is None:
            row["status"] = NEW
        elif row["ratio"] is None or row["baseline_ratio"] is None or row["baseline_ratio"] <= 0:
            row["status"] = NO_RATIO
        else:
            change = row["ratio"] / row["baseline_ratio"] - 1.0
            row["change"] = change
            if change > tolerance:
                row["status"], row["failed"] = REGRESSION, True
            elif row["ratio"] * (1.0 + tolerance) < row["baseline_ratio"]:
                row["status"] = FASTER
            else:
                row["status"] = OK
        rows.append(row)
    return GateResult(rows=rows, tolerance=tolerance, compared=baseline is not None)


def _secs(v) -> str:
    if v is None:
        return "–"
    return f"{v * 1e3:.1f} ms" if v < 1 else f"{v:.2f} s"


def format_table(result: GateResult) -> str:
    """The perf table: benchmark, median time, ratio, baseline ratio, change, status."""
    head = ["benchmark", "median", "ratio", "cpu ratio"] + (["baseline", "change", "status"] if result.compared
                                                            else [])
    body = []
    for r in result.rows:
        wall, cpu = r.get("wall_ratio", r["ratio"]), r.get("cpu_ratio")
        line = [r["name"], _secs(r["median_s"]), "–" if wall is None else f"{wall:.3f}",
                "–" if cpu is None else f"{cpu:.3f}"]
        if result.compared:
            # the baseline of the ratio the gate compared (marked * for the wall-clock ratio)
            line += ["–" if r["baseline_ratio"] is None else f"{r['baseline_ratio']:.3f}"
                     + ("*" if r.get("metric") == "wall" else ""),
                     "–" if r["change"] is None else f"{100 * r['change']:+.0f} %", r["status"]]
        body.append(line)
    widths = [max(len(str(x)) for x in col) for col in zip(head, *body)] if body else [len(h) for h in head]
    fmt = lambda cells: "  ".join(str(c).ljust(w) if i == 0 else str(c).rjust(w)  # noqa: E731
                                  for i, (c, w) in enumerate(zip(cells, widths)))
    lines = [fmt(head), "  ".join("-" * w for w in widths)] + [fmt(b) for b in body]
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------------- running
def repo_root() -> Path:
    return Path(__file__).resolve().parent.parent


def benchmarks_dir() -> Path:
    d = repo_root() / "tests" / "benchmarks"
    if not d.is_dir():
        raise InputError(f"the benchmark suites are not here ({d}): `bench perf` needs a source checkout")
    return d


def pinned_cpus(cpus: int) -> list[int] | None:
    """The CPUs the suite is pinned to: the last ``cpus`` of this process's allowed set (None: no pinning,
    ``cpus`` = 0 or no ``sched_setaffinity`` on this platform)."""
    if cpus <= 0 or not hasattr(os, "sched_getaffinity"):
        return None
    allowed = sorted(os.sched_getaffinity(0))
    return allowed[-cpus:] if cpus < len(allowed) else allowed


def run_suite(*, quick: bool = False, select: list[str] | None = None, keyword: str | None = None,
              n_rounds: int | None = None, cpus: int = 1, stream=None) -> tuple[int, dict | None]:
    """Run the benchmark suites once in a fresh ``python -m pytest``; return (exit code, summary or None).

    ``select``: pytest node ids to run instead of the whole ``tests/benchmarks`` (reruns); ``keyword``: ``-k``.
    ``cpus``: pin the suite (and the worker processes it starts) to that many CPUs (default 1; 0 = no
    pinning).  On one CPU a multi-threaded benchmark runs like the single-threaded reference whatever the
    number of free cores: unpinned, the CPU-time ratio of ``evaluate`` (a worker thread overlapping the main
    one) ranged 43–66 over runs on the shared machine as the other core came and went; pinned, 43–45.
    pytest's own output goes to ``stream`` (default: this process's stderr).
    """
    bdir = benchmarks_dir()
    root = repo_root()
    env = dict(os.environ)
    env[ENV_MODE] = "quick" if quick else "full"
    if n_rounds:
        env[ENV_ROUNDS] = str(int(n_rounds))
    for k in THREAD_ENV:
        env.setdefault(k, "1")
    with tempfile.TemporaryDirectory(prefix="lsb-perf-") as tmp:
        out = Path(tmp) / "benchmark.json"
        cmd = [sys.executable, "-m", "pytest", *(select or [str(bdir.relative_to(root))]), "-m", "benchmark",
               "-p", "no:cacheprovider", "-q", "--benchmark-json", str(out), "--benchmark-sort=name",
               "--benchmark-columns=median,min,max,rounds"]
        if keyword:
            cmd += ["-k", keyword]
        pin = pinned_cpus(cpus)
        pre = (lambda: os.sched_setaffinity(0, pin)) if pin else None
        target = stream if stream is not None else sys.stderr
        try:
            fd = target.fileno()
        except (AttributeError, OSError, ValueError):  # a stream without a file descriptor (tests)
            fd = None
        if fd is not None:
            proc = subprocess.run(cmd, cwd=root, env=env, stdout=fd, stderr=fd, preexec_fn=pre)
        else:
            proc = subprocess.run(cmd, cwd=root, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                  text=True, preexec_fn=pre)
            target.write(proc.stdout)
        summary = None
        if out.exists():
            try:
                summary = summarise(json.loads(out.read_text(encoding="utf-8")))
            except (ValueError, InputError):
                summary = None
    if summary is not None:
        summary["threads"] = {k: env[k] for k in THREAD_ENV}
        summary["pinned_cpus"] = pin
    return proc.returncode, summary


def machine_note() -> dict:
    """Load average and core count now (for the metadata of a saved summary)."""
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        load = None
    return {"loadavg_now": load, "cpu_count": os.cpu_count(), "platform": platform.platform()}


def save_summary(summary: dict, path: str | Path, note: dict[str, Any] | None = None) -> Path:
    data = dict(summary)
    if note:
        data["note"] = note
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    tmp = p.with_name(p.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=False) + "\n", encoding="utf-8")
    tmp.replace(p)
    return p
