"""A run killed (SIGKILL to its whole process group) at random moments and resumed gives the uninterrupted run's
results cell by cell — every column but the ones that measure the machine — and leaves no temporary file."""

from __future__ import annotations

import random
import subprocess
import sys
import time
from pathlib import Path

from .core import Case, Ctx, exits_ok, kill_group, rows

GRID = ("--phantoms", "sphere,ellipsoid", "--n", "16,20", "--noise", "none", "--method", "marching_cubes",
        "--add-method", "flying_edges", "--add-method", "mc_taubin", "--jobs", "2", "--no-report")
#: columns that measure the machine or the session, not the result
MACHINE = {"wall_s", "peak_mem_mb"}
CASES = 5


def reference(ctx: Ctx) -> tuple[dict[str, dict], float]:
    """The uninterrupted run's rows by cell id, and its seconds; made once."""
    def make():
        out = ctx.root / "resume" / "reference"
        start = time.monotonic()
        res = ctx.bench("run", *GRID, "--out", str(out), timeout=300)
        if res.rc != 0 or len(rows(out)) != 12:
            raise RuntimeError(f"the reference run failed: {res.show()}")
        return {r["cell_id"]: r for r in rows(out)}, time.monotonic() - start
    return ctx.once("resume.reference", make)


def _killed(ctx: Ctx, args: list[str], after: float) -> int | None:
    """Start ``python -m bench ARGS``, SIGKILL its process group after ``after`` s; its exit code if it ended
    first."""
    proc = subprocess.Popen([sys.executable, "-m", "bench", *args], cwd=ctx.root, env=ctx.environ(),
                            start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        return proc.wait(timeout=after)
    except subprocess.TimeoutExpired:
        kill_group(proc)
        proc.wait()
        return None


def compare(want: dict[str, dict], folder: Path) -> str | None:
    """The first cell or column where ``folder``'s results differ from ``want``, or None."""
    got = {r["cell_id"]: r for r in rows(folder)}
    if sorted(got) != sorted(want):
        return f"cells {sorted(set(want) ^ set(got))[:3]} differ between the runs"
    for cid, row in want.items():
        for col, value in row.items():
            if col in MACHINE or col.endswith("_s"):
                continue
            if got[cid].get(col) != value:
                return f"{cid}: {col} = {got[cid].get(col)!r} after resuming, {value!r} uninterrupted"
    temps = [p.name for p in folder.rglob(".*.tmp*")]
    return f"temporary files left: {temps[:3]}" if temps else None


def cases() -> list[Case]:
    """Killed once or twice at random moments (seeded), then resumed to the end."""
    out = []
    for k in range(CASES):
        def check(ctx, k=k):
            want, seconds = reference(ctx)
            rng = random.Random(k)
            folder = ctx.root / "resume" / f"killed{k}"
            kills = [rng.uniform(0.5, max(1.0, seconds * 0.9)) for _ in range(1 + (k == CASES - 1))]
            first_args = ["run", *GRID, "--out", str(folder)]
            for i, after in enumerate(kills):
                args = first_args if i == 0 else ["run", "--resume", "--out", str(folder), "--jobs", "2",
                                                  "--no-report"]
                if _killed(ctx, args, after) is not None and i == 0:
                    break            # it finished before the kill: the resume below must still agree
            if (folder / "config.json").exists():
                res = ctx.bench("run", "--resume", "--out", str(folder), "--jobs", "2", "--no-report", timeout=300)
            else:                    # killed before the run had a folder: --resume refuses, so run it again
                res = ctx.bench(*first_args, timeout=300)
            return exits_ok(res) or compare(want, folder)
        out.append(Case("resume", f"kill-and-resume {k + 1}: SIGKILL at seeded random moment(s)", check))
    return out
