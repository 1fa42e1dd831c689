"""bench.run.runner under faults: SIGKILL of the whole run at random moments, a full disk.

The fault-injection test kills ``python -m bench run`` (the whole process group: runner, fork server and
workers) at 10 random moments, resuming after each kill; the final results.csv must hold the same metric values
as an uninterrupted run, and no temporary file may be left.  The default test uses a small grid written here
(9 cells at N = 24, the quick grid's methods); the literal quick grid is the ``slow`` variant.
"""

from __future__ import annotations

import csv
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from _fs import remount, small_tmpfs, temp_files

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
COST_COLUMNS = {"wall_s", "peak_mem_mb"}

SMALL_GRID = """\
name = "faults"
[grid]
phantoms = ["sphere"]
n = 24
seeds = [0, 1]
noise = [{ kind = "none" }, { kind = "gaussian", snr = "paper" }]
[[methods]]
name = "shape_gradient"
params = { alpha = 5.0, beta = 1.0 }
[[methods]]
name = "marching_cubes"
[[methods]]
name = "mc_taubin"
[metrics]
n_samples = 3000
"""


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    return env


def _cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "bench", "run", *args, "--jobs", "2", "--no-report"]


def _rows(path: Path) -> dict[str, dict]:
    with open(path, newline="") as fh:
        return {r["cell_id"]: {k: v for k, v in r.items() if k not in COST_COLUMNS} for r in csv.DictReader(fh)}


def _killed_at(args: list[str], seconds: float) -> bool:
    """Start a run in its own process group and SIGKILL the whole group after ``seconds``; True if it was
    still running then."""
    proc = subprocess.Popen(_cmd(*args), cwd=REPO, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        proc.wait(timeout=seconds)
        return False
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        return True


def _fault_injection(tmp_path: Path, grid_args: list[str], seed: int) -> dict:
    ref = tmp_path / "reference"
    t0 = time.perf_counter()
    done = subprocess.run(_cmd(*grid_args, "--out", str(ref)), cwd=REPO, env=_env(), capture_output=True,
                          text=True, timeout=600)
    t_ref = time.perf_counter() - t0
    assert done.returncode == 0, done.stderr[-2000:]
    expected = _rows(ref / "results.csv")

    out = tmp_path / "killed"
    rng = random.Random(seed)
    live_kills = 0
    for _ in range(10):
        resume = ["--resume"] if (out / "config.json").exists() else []  # killed before the config: start over
        # a random moment within the time the remaining cells would take (so most kills hit a running grid)
        left = 1.0 - len([p for p in (out / "cells").glob("[!.]*.json")]) / len(expected) if resume else 1.0
        live_kills += _killed_at([*grid_args, *resume, "--out", str(out)], rng.uniform(0.1, t_ref * max(left, 0.2)))
    final = subprocess.run(_cmd(*grid_args, "--resume", "--out", str(out)), cwd=REPO, env=_env(),
                           capture_output=True, text=True, timeout=600)
    assert final.returncode == 0, final.stderr[-2000:]
    got = _rows(out / "results.csv")
    assert list(got) == list(expected)                       # every cell once, in grid order
    for cid, row in expected.items():
        assert got[cid] == row, cid                          # identical metric values (cost columns aside)
    assert temp_files(out) == [], temp_files(out)
    assert not (out / "run.lock").exists() and not (out / "cache").exists()
    assert live_kills >= 7, f"only {live_kills} of 10 kills hit a running process"
    return {"t_ref": t_ref, "live_kills": live_kills}


@pytest.mark.heavy
def test_sigkill_at_10_random_moments_then_resume_gives_identical_results(tmp_path):
    cfg = tmp_path / "faults.toml"
    cfg.write_text(SMALL_GRID)
    _fault_injection(tmp_path, ["--config", str(cfg)], seed=16)


@pytest.mark.slow
def test_the_quick_grid_killed_10_times_and_resumed_gives_identical_results(tmp_path):
    _fault_injection(tmp_path, ["--quick"], seed=1616)


# ---------------------------------------------------------------------------------------------- disk full
def _simulate_enospc_after(monkeypatch, n_ok: int) -> None:
    """Without a tmpfs: the (n_ok+1)-th atomic rename and all later ones fail with ENOSPC."""
    import errno

    import geometry.files as gf

    real = os.replace
    calls = {"n": 0}

    def replace(src, dst):
        calls["n"] += 1
        if calls["n"] > n_ok:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(gf.os, "replace", replace)


@pytest.mark.parametrize("how", ["tmpfs", "simulated"])
def test_a_full_disk_is_one_line_with_a_resume_hint_and_leaves_no_temp_files(tmp_path, monkeypatch, capsys, how):
    """A real full disk (a 200 KiB tmpfs; the run needs ~330 KiB) when running as root, and always a simulated
    ENOSPC (the 7th atomic write fails): exit 2, one line naming the file and the cause, a resume hint, no
    temporary file, the lock released; with room again, --resume completes the run."""
    from contextlib import nullcontext

    from bench.cli import main

    cfg = tmp_path / "faults.toml"
    cfg.write_text(SMALL_GRID)
    with (small_tmpfs(tmp_path / "disk", size="200k") if how == "tmpfs" else nullcontext()) as disk:
        if how == "tmpfs" and disk is None:
            pytest.skip("mounting a tmpfs needs root (the simulated variant covers this)")
        out = (disk or tmp_path) / "run"
        if disk is None:
            _simulate_enospc_after(monkeypatch, 6)
        code = main(["run", "--config", str(cfg), "--out", str(out), "--jobs", "2", "--no-report",
                     "--save-meshes"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2
        assert err[-1].startswith("error: cannot write ") and "No space left on device" in err[-1], err
        assert "--resume --out" in err[-1] and "Traceback" not in "\n".join(err)
        assert temp_files(out) == [], temp_files(out)
        assert not (out / "run.lock").exists()
        # room again: the resume completes the run from the cells that were saved
        if disk is not None:
            assert remount(disk, "size=64m")
        else:
            monkeypatch.undo()
        assert main(["run", "--config", str(cfg), "--resume", "--out", str(out), "--jobs", "2",
                     "--no-report"]) == 0
        assert len(_rows(out / "results.csv")) == 9 and temp_files(out) == []


# ---------------------------------------------------------------------------------------------- tampering plug-ins
def test_a_plugin_that_writes_a_record_and_deletes_config_json_leaves_a_sound_resumable_folder(tmp_path, capsys):
    """A record a plug-in wrote — even sealed with the suite's own seal() — is set aside (``.rejected``), not
    taken as a finished cell; config.json removed mid-run is written again at the end (issue 40 item 2)."""
    from bench.cli import main
    from tamper_plugins import FORGED_ID

    out = tmp_path / "run"
    grid = ["--quick", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "2000",
            "--import", "tamper_plugins", "--jobs", "1", "--no-report"]
    assert main(["run", *grid, "--method", f"writes_record:folder={out}", "--add-method",
                 f"deletes_config:folder={out}", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"1 cell record(s) not written by the runner (a plug-in's?) set aside as cells/*.json.rejected: " \
           f"{FORGED_ID}" in err
    assert not (out / "cells" / f"{FORGED_ID}.json").exists()
    assert (out / "cells" / f"{FORGED_ID}.json.rejected").exists() and (out / "config.json").is_file()
    with open(out / "results.csv", newline="") as fh:
        assert sorted(r["method"] for r in csv.DictReader(fh)) == ["deletes_config", "writes_record"]
    assert main(["report", str(out)]) == 0                               # the folder agrees with its records
    (out / "config.json").unlink()                                       # as if killed before the end
    assert main(["run", "--resume", "--out", str(out), "--jobs", "1", "--no-report"]) == 0   # run.json keeps it
    assert "2 cells: 2 ok" in capsys.readouterr().out
