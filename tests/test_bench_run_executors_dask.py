"""`python -m bench run --executor dask`: same results as the local executor, worker death, timeouts, bad input."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

from bench.cli import main  # noqa: E402
from bench.config import config_from_dict  # noqa: E402
from bench.run import expand_grid, run_grid  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
# columns that measure the machine, not the result
COST_COLUMNS = {"wall_s", "peak_mem_mb"}
# the quick grid on one phantom (CI time), plus a method that raises and one that kills its own process
QUICK = ["--quick", "--phantoms", "sphere", "--import", "runner_plugins", "--add-method", "failing",
         "--add-method", "crashing"]


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(TESTS), str(REPO)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    return env


def _bench(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bench", "run", *args], cwd=REPO, env=_env(),
                          capture_output=True, text=True, timeout=300)


def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


# ---------------------------------------------------------------------------------------------- same results
@pytest.fixture(scope="module")
def local_and_dask(tmp_path_factory):
    base = tmp_path_factory.mktemp("dask")
    # no memory limit, as on the Dask workers (a crash row names the local limit in force)
    local = _bench(*QUICK, "--jobs", "2", "--memory-limit", "0", "--no-report", "--out", str(base / "local"))
    assert local.returncode == 0, local.stderr[-3000:]
    dask = _bench(*QUICK, "--executor", "dask", "--workers", "2", "--out", str(base / "dask"))
    assert dask.returncode == 0, dask.stderr[-3000:]
    return base / "local", base / "dask", dask


@pytest.mark.heavy
def test_quick_grid_on_a_local_dask_cluster_equals_the_local_executor_and_records_no_version_differences(
        local_and_dask):
    local, dask, proc = local_and_dask
    ref, got = _rows(local / "results.csv"), _rows(dask / "results.csv")
    assert [r["cell_id"] for r in got] == [r["cell_id"] for r in ref]  # every cell once, grid order
    assert list(got[0]) == list(ref[0])  # the same columns
    for r, e in zip(got, ref):
        for col in r:
            if col not in COST_COLUMNS:
                assert r[col] == e[col], (r["cell_id"], col, r[col], e[col])
    status = {r["method"]: r["status"] for r in got}
    assert status["failing"] == "failed" and status["crashing"] == "failed"  # isolation as with the local pool
    assert all("SIGKILL" in r["error"] for r in got if r["method"] == "crashing")
    # on one machine the workers run the same versions: nothing recorded, nothing said
    executor = json.loads((dask / "run.json").read_text())["sessions"][-1]["executor"]
    assert executor["executor"] == "dask" and executor["workers_connected"] == 2
    assert "version_differences" not in executor and "version differs" not in proc.stderr
    assert sum(r["status"] == "ok" for r in got) == 6
    assert "10 cells: 6 ok, 4 failed, 0 timeout" in proc.stdout
    assert (dask / "index.html").exists()  # the report from the same per-cell store
    assert len(list((dask / "cells").glob("*.json"))) == 10
    session = json.loads((dask / "run.json").read_text())["sessions"][-1]
    assert session["executor"]["executor"] == "dask" and session["executor"]["workers"] == 2


# ---------------------------------------------------------------------------------------------- worker death
class _KillAWorkerAfterTheFirstResult:
    """Wraps a DaskExecutor: after the first result, SIGKILL a worker process that is running a cell."""

    def __init__(self, executor):
        self.executor = executor
        self.victim = None

    def describe(self):
        return self.executor.describe()

    def run(self, cells, on_start, on_result):
        client = self.executor.client

        def result(cell, res):
            on_result(cell, res)
            if self.victim is None:
                busy = {}
                deadline = time.monotonic() + 10
                while not busy and time.monotonic() < deadline:
                    busy = {w: keys for w, keys in client.processing().items() if keys}
                    time.sleep(0.05)
                worker = next(iter(busy))
                pid = client.run(os.getpid, workers=[worker])[worker]
                self.victim = (pid, list(busy[worker]))
                os.kill(pid, signal.SIGKILL)

        self.executor.run(cells, on_start, result)


def _napping_config(timeout: float | None = None, sleepy: bool = False):
    methods = [{"name": "napping", "params": {"seconds": 1.0}, "sweep": {"tag": [0, 1, 2, 3, 4, 5]}}]
    if sleepy:
        methods.append({"name": "sleepy", "params": {"seconds": 60.0}})
    cfg = config_from_dict({
        "grid": {"phantoms": ["sphere"], "n": [16], "noise": [{"kind": "none"}]},
        "methods": methods, "metrics": {"n_samples": 2000},
        "run": {"timeout": timeout or 0, "imports": ["dask_plugins", "runner_plugins"]},
    })
    cfg.validate()
    return cfg


@pytest.fixture
def plugins_on_path():
    sys.path.insert(0, str(TESTS))  # the LocalCluster's workers inherit sys.path
    yield
    sys.path.remove(str(TESTS))


@pytest.mark.heavy
def test_a_worker_killed_mid_cell_still_gives_every_cell_exactly_once(tmp_path, plugins_on_path):
    """Also: a per-cell timeout on the Dask path, and --resume after cells were lost from the store."""
    from bench.run.executors.dask import DaskExecutor

    cfg = _napping_config(timeout=6, sleepy=True)
    cells = expand_grid(cfg)
    out = tmp_path / "run"
    with DaskExecutor(workers=2, timeout=cfg.timeout, cache_dir=str(out / "cache"), imports=cfg.imports) as ex:
        killer = _KillAWorkerAfterTheFirstResult(ex)
        summary = run_grid(cfg, out, executor=killer, progress=False)
    pid, keys = killer.victim
    assert keys, "the killed worker was running a cell"
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # really dead
    rows = _rows(out / "results.csv")
    assert [r["cell_id"] for r in rows] == [c.cell_id for c in cells]  # every cell exactly once
    assert sorted(p.stem for p in (out / "cells").glob("*.json")) == sorted(c.cell_id for c in cells)
    status = {r["label"]: (r["status"], r["error"]) for r in rows}
    assert all(status[f"napping[tag={t}]"][0] == "ok" for t in range(6)), status
    assert status["sleepy"][0] == "timeout" and "6 s" in status["sleepy"][1]  # killed on the worker, row kept
    assert (summary.ok, summary.failed, summary.timeout) == (6, 0, 1)

    # --resume through the Dask path reruns only the cells missing from the store
    for c in cells[:2]:
        (out / "cells" / f"{c.cell_id}.json").unlink()
    # (the same config: --resume refuses another one; the timed-out sleepy cell counts as finished)
    again = run_grid(cfg, out, resume=True, progress=False,
                     executor=DaskExecutor(workers=1, timeout=6, imports=cfg.imports))
    assert again.skipped == 5 and again.ran == 2
    assert sorted(r["status"] for r in _rows(out / "results.csv")) == ["ok"] * 6 + ["timeout"]


@pytest.mark.heavy
def test_a_cell_that_keeps_killing_its_workers_becomes_a_failed_row(tmp_path, plugins_on_path):
    """Dask retries a cell whose worker died (allowed-failures, here 1); then KilledWorker -> a failed row."""
    import dask

    from bench.run.executors.dask import DaskExecutor

    cfg = config_from_dict({
        "grid": {"phantoms": ["sphere"], "n": [16], "noise": [{"kind": "none"}]},
        "methods": [{"name": "worker_killer", "params": {"seconds": 1.0}}, {"name": "marching_cubes"}],
        "metrics": {"n_samples": 2000}, "run": {"imports": ["dask_plugins"]},
    })
    cfg.validate()
    out = tmp_path / "run"
    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        with DaskExecutor(workers=2, imports=cfg.imports, cache_dir=str(out / "cache")) as ex:
            summary = run_grid(cfg, out, executor=ex, progress=False)
    rows = {r["method"]: r for r in _rows(out / "results.csv")}
    assert len(_rows(out / "results.csv")) == 2 and set(rows) == {"worker_killer", "marching_cubes"}
    assert rows["worker_killer"]["status"] == "failed" and "KilledWorker" in rows["worker_killer"]["error"]
    assert rows["marching_cubes"]["status"] == "ok"
    assert (summary.ok, summary.failed) == (1, 1)


# ---------------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize("args, message", [
    (["--executor", "dask", "--scheduler", "http://host:8786"], "unknown address scheme 'http'"),
    (["--executor", "dask", "--scheduler", "tcp://a b"], "not a scheduler address"),
    (["--executor", "dask", "--scheduler", "host"], "missing port number"),
    (["--executor", "dask", "--scheduler", "tcp://host:99999"], "port out of range"),
    (["--executor", "dask", "--scheduler", "tcp://host:8786", "--workers", "2"], "--workers sets the size"),
    (["--executor", "dask", "--jobs", "2"], "use --workers N"),
    (["--scheduler", "tcp://host:8786"], "--scheduler needs --executor dask"),
    (["--workers", "2"], "--workers needs --executor dask"),
])
def test_bad_executor_arguments_exit_2(args, message, tmp_path, capsys):
    assert main(["run", "--quick", *args, "--out", str(tmp_path / "o"), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args", [["--executor", "threads"], ["--executor", "dask", "--workers", "0"]])
def test_malformed_executor_options_are_usage_errors(args, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "--quick", *args, "--dry-run"])
    assert exc.value.code == 2


def test_unreachable_scheduler_exits_2_before_any_cell(tmp_path, capsys):
    import socket

    import dask

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    out = tmp_path / "o"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):   # Dask's own knob, not the suite's
        assert main(["run", "--quick", "--executor", "dask", "--scheduler", f"tcp://127.0.0.1:{port}",
                     "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"cannot reach the Dask scheduler at tcp://127.0.0.1:{port}" in err and "Traceback" not in err
    assert not list(out.glob("cells/*.json"))


def test_a_scheduler_without_workers_is_one_error_naming_the_command_that_starts_them():
    from distributed import LocalCluster

    from bench.run.executors.dask import DaskExecutor
    from phantoms import InputError

    with LocalCluster(n_workers=0, processes=False, dashboard_address=None) as cluster:
        address = cluster.scheduler_address
        with pytest.raises(InputError, match=f"no Dask worker connected to {address} within 1 s") as exc:
            DaskExecutor(scheduler=address, wait_for_workers_s=1).connect()
    assert f"`dask worker {address}`" in str(exc.value)


def test_without_dask_installed_the_message_names_the_extra(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    assert main(["run", "--quick", "--executor", "dask", "--out", str(tmp_path / "o"), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert 'pip install -e ".[dask]"' in err and "Traceback" not in err


# ---------------------------------------------------------------------------------------------- same code
def test_the_dask_executor_stays_within_150_lines():
    """The executor leaves scheduling, retries, address parsing and version checks to distributed."""
    n = len((REPO / "bench" / "run" / "executors" / "dask.py").read_text().splitlines())
    assert n <= 150, f"bench/run/executors/dask.py has {n} lines (at most 150)"


@pytest.mark.heavy
def test_a_worker_with_other_package_versions_is_accepted_with_the_difference_recorded(plugins_on_path):
    from bench.run.executors.dask import DaskExecutor

    with DaskExecutor(workers=1, imports=["dask_other_numpy"]) as ex:
        recorded = ex.describe()["version_differences"]
    assert any("numpy" in text and "0.1" in text for text in recorded), recorded


@pytest.mark.heavy
def test_a_worker_on_another_commit_stops_the_run_before_any_cell(tmp_path):
    from bench.run.provenance import git_commit

    if git_commit() is None:
        pytest.skip("not a git checkout: the commit is not compared")
    out = tmp_path / "o"
    proc = _bench("--quick", "--phantoms", "sphere", "--import", "dask_foreign_commit", "--executor", "dask",
                  "--workers", "1", "--out", str(out))
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "git commit 0123456789ab" in proc.stderr and "Traceback" not in proc.stderr
    assert not list(out.glob("cells/*.json"))
