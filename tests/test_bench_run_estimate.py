"""Cost models and the refusal of cells whose estimate exceeds their time limit (bench/run/estimate.py).

Reach for the Spheres at N = 256 under a 10 min timeout must fail at once with the estimate in its error (no
volume built, no method run), and run when forced; a method without a cost model (or with a broken one) is
never refused; the built-in models are within a factor of 3 of a measured small run.
"""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import cost_plugins  # noqa: F401 - registers costly / uncosted / broken_model in this process
from bench.cli import main
from bench.config import config_from_dict
from bench.run import Cell, run_cell, run_grid
from bench.run.estimate import format_duration, method_budget, method_estimate, refusal
from bench.run.limits import TimeLimits
from methods import crossing_cells, get_method
from phantoms import InputError, get_phantom

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
REFUSED = re.compile(r"^estimated [\d.]+ (min|h) > timeout 10 min \(use --force to run it anyway\)$")


def _cell(method: str, n: int, **params) -> Cell:
    return Cell.from_dict({"cell_id": f"sphere-{method}-n{n}", "phantom": "sphere", "variant": "sdf", "n": n,
            "extent": 2.5, "noise": "none", "snr_requested": None, "seed": 0, "method": method, "label": method,
            "params": params, "n_samples": 1000, "imports": []})


def _cfg(method: str, n: int, timeout: float, **run) -> object:
    cfg = config_from_dict({"grid": {"phantoms": ["sphere"], "n": n}, "methods": [{"name": method}],
                            "metrics": {"n_samples": 2000}, "run": {"timeout": timeout, "imports": ["cost_plugins"],
                                                                    **run}})
    cfg.validate()
    return cfg


def _rows(out: Path) -> list[dict]:
    with open(out / "results.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def _bench(*args) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    return subprocess.run([sys.executable, "-m", "bench", "run", *args], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=300)


# ---------------------------------------------------------------------------------------------- the check itself
def test_durations_read_as_people_read_them():
    assert format_duration(45) == "45 s"
    assert format_duration(47 * 60) == "47 min"
    assert format_duration(3.2 * 3600) == "3.2 h"


def test_the_budget_is_the_tightest_limit_on_the_method():
    assert method_budget(TimeLimits()) is None
    assert method_budget(TimeLimits(score=5)) is None          # scoring comes after the method: not its budget
    assert method_budget(TimeLimits(cell=600)) == (600, "timeout")
    assert method_budget(TimeLimits(cell=600, method=60)) == (60, "method timeout")
    assert method_budget(TimeLimits(cell=30, method=60)) == (30, "timeout")


def test_reach_for_the_spheres_at_256_is_refused_under_ten_minutes_with_its_estimate():
    cell = _cell("reach_for_the_spheres", 256)
    estimate = method_estimate(cell)
    assert estimate is not None and estimate > 600
    result = refusal(cell, TimeLimits(cell=600))
    assert result.row.status == "failed"
    assert REFUSED.match(result.row.error), result.row.error
    assert result.row.estimate_s == pytest.approx(estimate, rel=1e-3)
    assert refusal(cell, TimeLimits(cell=600), force=True) is None
    assert refusal(cell, TimeLimits()) is None                 # no limit: nothing to exceed
    assert refusal(cell, TimeLimits(cell=estimate * 2)) is None


def test_methods_without_a_model_or_with_a_broken_one_are_never_refused():
    for method in ("uncosted", "broken_model", "marching_cubes"):
        assert method_estimate(_cell(method, 512)) is None
        assert refusal(_cell(method, 512), TimeLimits(cell=0.001)) is None
    assert method_estimate(_cell("reach_for_the_spheres", 0)) is None   # a user volume's native grid


def test_the_models_grow_with_n_and_with_the_surface():
    for name in ("reach_for_the_spheres", "dual_contouring", "distmesh"):
        m = get_method(name)
        small, big = m.estimate_seconds(32), m.estimate_seconds((256, 256, 256))
        assert 0 < small < big, name
        assert m.estimate_seconds(64, 3 * 3000) >= m.estimate_seconds(64, 3000), name


# ---------------------------------------------------------------------------------------------- in a grid run
def test_a_grid_cell_over_its_estimate_fails_at_once_with_the_estimate_in_its_row(tmp_path):
    t0 = time.perf_counter()
    summary = run_grid(_cfg("reach_for_the_spheres", 256, 600), tmp_path / "run", jobs=1, progress=False)
    elapsed = time.perf_counter() - t0
    assert summary.failed == 1 and summary.ran == 1
    assert elapsed < 30, elapsed                                # no 256³ volume, no method: at once
    (row,) = _rows(tmp_path / "run")
    assert row["status"] == "failed" and REFUSED.match(row["error"]), row["error"]
    assert float(row["estimate_s"]) > 600
    assert not (tmp_path / "run" / "cache").exists() or not any((tmp_path / "run" / "cache").iterdir())


class _InlineExecutor:
    """Runs each cell in this process (no worker start-up: the check under test happens before any executor)
    and remembers which cells it was given."""

    def __init__(self) -> None:
        self.given: list[str] = []

    def run(self, cells, on_start, on_result) -> None:
        for cell in cells:
            self.given.append(cell.cell_id)
            on_start(cell)
            on_result(cell, run_cell(cell))


def test_force_runs_the_cell_and_a_model_less_method_runs_anyway(tmp_path):
    ex = _InlineExecutor()
    summary = run_grid(_cfg("costly", 16, 600), tmp_path / "refused", executor=ex, progress=False)
    (row,) = _rows(tmp_path / "refused")
    assert summary.failed == 1 and ex.given == []              # never handed to the executor
    assert row["error"].startswith("estimated 60 min > timeout 10 min"), row["error"]
    for out, cfg, force in ((tmp_path / "forced", _cfg("costly", 16, 600), True),
                            (tmp_path / "config_forced", _cfg("costly", 16, 600, force=True), False),
                            (tmp_path / "uncosted", _cfg("uncosted", 16, 600), False),
                            (tmp_path / "broken_model", _cfg("broken_model", 16, 600), False)):
        ex = _InlineExecutor()
        summary = run_grid(cfg, out, executor=ex, progress=False, force=force)
        (row,) = _rows(out)
        assert len(ex.given) == 1 and row["status"] == "ok", (out.name, row["error"])
        assert not row.get("estimate_s"), out.name


def test_a_refused_cell_is_completed_by_resume_retry_failed_force(tmp_path):
    out, cfg = tmp_path / "run", _cfg("costly", 16, 600)
    run_grid(cfg, out, executor=_InlineExecutor(), progress=False)
    ex = _InlineExecutor()
    summary = run_grid(cfg, out, executor=ex, progress=False, resume=True, retry_failed=True, force=True)
    (row,) = _rows(out)
    assert summary.ok == 1 and len(ex.given) == 1 and row["status"] == "ok", row["error"]
    run_json = json.loads((out / "run.json").read_text())
    assert [s["force"] for s in run_json["sessions"]] == [False, True]


def test_run_force_is_a_config_key_that_round_trips_and_rejects_non_booleans():
    cfg = _cfg("costly", 24, 600, force=True)
    assert cfg.force and config_from_dict(cfg.to_dict()).force
    assert "force" not in _cfg("costly", 24, 600).to_dict()["run"]     # unchanged fingerprints without it
    with pytest.raises(InputError, match="run.force: expected true or false"):
        config_from_dict({"grid": {"phantoms": ["sphere"]}, "methods": [{"name": "marching_cubes"}],
                          "run": {"force": "yes"}})


_COMMON = ["--phantoms", "sphere", "--noise", "none", "--n", "256", "--method", "reach_for_the_spheres",
           "--n-samples", "2000", "--jobs", "1", "--no-report"]


def test_the_command_line_refuses_reach_for_the_spheres_at_256_under_ten_minutes(tmp_path, capsys):
    assert main(["run", *_COMMON, "--timeout", "600", "--out", str(tmp_path / "refused")]) == 0
    (row,) = _rows(tmp_path / "refused")
    assert row["status"] == "failed" and REFUSED.match(row["error"]), row["error"]
    assert "0 ok, 1 failed" in capsys.readouterr().out


@pytest.mark.heavy
def test_force_on_the_command_line_attempts_the_cell(tmp_path):
    # forced, under a 3 s limit: the cell is started (and killed at its limit) by the local executor
    proc = _bench(*_COMMON, "--timeout", "3", "--force", "--out", str(tmp_path / "forced"))
    assert proc.returncode == 0, proc.stderr[-2000:]
    (row,) = _rows(tmp_path / "forced")
    assert row["status"] == "timeout" and "estimated" not in row["error"], row["error"]


# ---------------------------------------------------------------------------------------------- the fits
def _measured_vs_estimate(method: str, phantom: str, n: int, repeats: int = 1) -> tuple[float, float]:
    """The CPU seconds of a run — the median of ``repeats`` runs (what the models estimate: a quiet machine's
    wall time, which the load of a shared machine does not inflate) — and the model's estimate for the volume."""
    m = get_method(method)
    m.reconstruct(get_phantom("sphere").volume(n=16))         # the one-time costs (compilation, imports)
    vol = get_phantom(phantom).volume(n=n)
    times = []
    for _ in range(repeats):
        c0 = time.process_time()
        m.reconstruct(vol)
        times.append(time.process_time() - c0)
    return float(np.median(times)), m.estimate_seconds(vol.shape, crossing_cells(vol))


def test_distmesh_estimate_grows_as_measured_and_is_of_the_measured_order():
    """The model's constants were fitted to one machine's timings; another CPU runs DistMesh at another speed (a
    2026-12 Intel Xeon: 3.8-4.5x faster than the fit), so across machines what must hold is the growth with N
    (48 -> 96, within a factor 1.5 of the model's 5.8x) and the order of magnitude: at most 6x the estimate, at
    least a tenth of it (the fit errs on the slow side, about 2x at N = 96 on its own machine, and an AMD EPYC CI
    machine has run the N = 96 sphere in 0.21 s CPU against an estimate of 1.29 s)."""
    # the median of 3: one 0.06 s run at N = 48 is at the mercy of the scheduler on a busy CI machine
    cpu48, est48 = _measured_vs_estimate("distmesh", "sphere", 48, repeats=3)
    cpu96, est96 = _measured_vs_estimate("distmesh", "sphere", 96, repeats=3)
    growth, model = cpu96 / cpu48, est96 / est48
    assert model / 1.5 <= growth <= model * 1.5, (cpu48, cpu96, est48, est96, os.getloadavg())
    assert est96 / 10 <= cpu96 <= est96 * 6, (cpu96, est96, os.getloadavg())


@pytest.mark.heavy
@pytest.mark.parametrize("method", ["reach_for_the_spheres", "dual_contouring"])
def test_peer_estimates_are_of_the_measured_order(method):
    # the bunny: Reach for the Spheres' model is that of a surface not tangent to every sphere (the clean sphere
    # converges by tangency in ≈ 15 steps, 6-10x under its estimate, so it would not test the model).  At most 3x
    # the estimate (a cell refused as too slow must be), at least a fifth of it: the models were fitted on one
    # machine and an AMD EPYC CI machine ran dual contouring's bunny in 2.49 s CPU against 7.70 s estimated
    cpu, estimate = _measured_vs_estimate(method, "bunny", 32)
    assert estimate / 5 <= cpu <= estimate * 3, (cpu, estimate, os.getloadavg())


# ---------------------------------------------------------------------------------------------- time left
def _grid_cell(label: str, n: int, seed: int, method: str = "marching_cubes", source: str = "") -> Cell:
    return Cell.from_dict({"cell_id": f"{label}-n{n}-s{seed}-{source}", "phantom": "sphere", "variant": "sdf",
                           "n": n, "extent": 2.5, "noise": "none", "snr_requested": None, "seed": seed,
                           "method": method, "label": label, "params": {}, "n_samples": 1000, "imports": [],
                           **({"source": source} if source else {})})


def test_the_time_left_is_learnt_per_method_and_input_size_with_its_range():
    """A fast and a slow method at two sizes: the time left is the sum of each remaining cell's group mean, scaled
    by the parallelism seen; not the run's mean rate times the cells left."""
    from bench.run.estimate import RemainingTime

    fast = [_grid_cell("fast", 24, s) for s in range(10)]
    slow = [_grid_cell("slow", 24, s) for s in range(10)]
    big = [_grid_cell("fast", 48, s) for s in range(2)]
    left = RemainingTime(fast + slow + big, now=0.0)
    assert left.text(0.0) == ""                                   # nothing learnt yet
    clock = 0.0
    for cell, seconds in [(fast[0], 1.0), (fast[1], 1.2), (slow[0], 10.0), (slow[1], 11.0)]:  # one job
        left.start(cell, clock)
        clock += seconds
        left.finish(cell, seconds, clock)
    mid, lo, hi = left.expected(clock)
    # 8 fast × 1.1 s + 8 slow × 10.5 s + 2 fast at N = 48 × 1.1 s × 2³, one at a time
    assert mid == pytest.approx(8 * 1.1 + 8 * 10.5 + 2 * 1.1 * 8)
    assert lo < mid < hi and hi - lo < mid                       # a range, not a point
    # a run's mean rate would say 12 s / 3 cells × 9 cells left = 36 s where 8 fast cells and a slow one are left
    mix = RemainingTime(fast[:10] + slow[:2], now=0.0)
    for t, (cell, seconds) in enumerate([(fast[0], 1.0), (fast[1], 1.0), (slow[0], 10.0)]):
        mix.finish(cell, seconds, 12.0 * (t + 1) / 3)
    assert mix.expected(12.0)[0] == pytest.approx(8 * 1.0 + 10.0)
    text = left.text(clock)
    assert re.fullmatch(r"about [\d.]+ (s|min) left \([\d.]+ (s|min)–[\d.]+ (s|min)\)", text), text
    # two jobs: cells overlap, twice the cell-seconds per second of wall time
    par = RemainingTime(fast[:4], now=0.0)
    for cell in fast[:2]:
        par.start(cell, 0.0)
    for cell in fast[:2]:
        par.finish(cell, 2.0, 2.0)
    assert par.expected(2.0)[0] == pytest.approx(2 * 2.0 / 2)
    # a cell refused before it ran (cell_s 0) teaches nothing; a method not seen yet gets the median cell
    other = RemainingTime([_grid_cell("a", 24, 0), _grid_cell("b", 24, 0), _grid_cell("c", 24, 0)], now=0.0)
    other.finish(_grid_cell("a", 24, 0), 0.0, 0.0)
    assert other.expected(0.0) is None
    other.finish(_grid_cell("b", 24, 0), 4.0, 4.0)
    assert other.expected(4.0)[0] == pytest.approx(4.0)


def test_the_labels_of_one_label_map_share_its_input_size():
    from bench.run.estimate import RemainingTime

    cells = [_grid_cell("mc", 0, 0, source=f"volume:seg.nii.gz?label={k}") for k in (1, 2, 3)]
    left = RemainingTime(cells, now=0.0)
    left.finish(cells[0], 6.0, 6.0)
    assert left.expected(6.0)[0] == pytest.approx(12.0)


def test_a_labels_cost_follows_its_surface_also_for_a_method_not_seen_on_it(tmp_path):
    """Labels of one map: the part of a cell that grows with the surface (method, validity, metrics, pictures)
    scales with the label's surface; a method not seen on the map takes the others' fixed and per-surface seconds."""
    import nibabel as nib

    from bench.run.estimate import RemainingTime
    from phantoms.labels import label_surfaces

    lab = np.zeros((40, 40, 40), np.uint8)
    lab[2:30, 2:30, 2:30] = 1                       # a big cube
    lab[33:37, 33:37, 33:37] = 2                    # a small one
    nib.save(nib.Nifti1Image(lab, np.eye(4)), str(tmp_path / "seg.nii.gz"))
    spec = f"volume:{tmp_path / 'seg.nii.gz'}"
    surfaces = label_surfaces(f"{spec}?label=1")
    assert surfaces == {1: 28 ** 3 - 26 ** 3, 2: 4 ** 3 - 2 ** 3}
    cells = [_grid_cell(m, 0, 0, source=f"{spec}?label={k}") for m in ("mc", "sn") for k in (1, 2)]
    left = RemainingTime(cells, now=0.0)
    left.finish(cells[0], 10.0, 10.0, scaling_s=8.0)      # mc on label 1: 2 s fixed, 8 s over its surface
    per = 8.0 / surfaces[1]
    small = 2.0 + per * surfaces[2]
    assert left.expected(10.0)[0] == pytest.approx(small + 10.0 + small)   # mc label 2, sn label 1 and 2
