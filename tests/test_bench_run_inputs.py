"""bench.run.inputs: one check of a run's inputs, made once, before any executor starts."""

from __future__ import annotations

import json

import pytest

import bench.run.inputs
import bench.run.runner
from bench.cli import main
from bench.config import config_from_dict
from bench.run import run_grid
from bench.run.inputs import ExecutorSpec, check_run_inputs
from phantoms import InputError

GRID = '[grid]\nphantoms = ["sphere"]\nn = [16]\n[[methods]]\nname = "marching_cubes"\n'


def _cfg(n: int = 16):
    cfg = config_from_dict({"grid": {"phantoms": ["sphere"], "n": [n], "noise": [{"kind": "none"}]},
                            "methods": [{"name": "marching_cubes"}], "metrics": {"n_samples": 2000}})
    cfg.validate()
    return cfg


@pytest.mark.parametrize("spec, kwargs, message", [
    (ExecutorSpec("local", workers=2), {}, "--workers needs --executor dask"),
    (ExecutorSpec("local", scheduler="tcp://h:8786"), {}, "--scheduler needs --executor dask"),
    (ExecutorSpec("dask"), {"jobs": 2}, "--jobs sizes the local process pool"),
    (ExecutorSpec("dask"), {"memory_gb": 4.0}, "--memory-limit applies to the local executor"),
    (ExecutorSpec("dask", workers=0), {}, "--workers must be >= 1"),
    (ExecutorSpec("dask", "tcp://h:8786", workers=2), {}, "--workers sets the size of the local Dask cluster"),
    (None, {"retry_failed": True}, "--retry-failed needs --resume"),
    (None, {"allow_mixed_code": True}, "--allow-mixed-code needs --resume"),
    (None, {"timeout": 1e12}, "--timeout: must be between 0"),
])
def test_options_that_do_not_fit_are_one_error(spec, kwargs, message):
    pytest.importorskip("distributed")
    with pytest.raises(InputError, match=message):
        check_run_inputs(_cfg(), None, executor=spec, **kwargs)


def test_the_scheduler_address_comes_back_as_distributed_reads_it():
    pytest.importorskip("distributed")
    spec = check_run_inputs(_cfg(), None, executor=ExecutorSpec("dask", "127.0.0.1:8786"))
    assert spec == ExecutorSpec("dask", "tcp://127.0.0.1:8786")
    executor = object()              # an executor object of the caller's is taken as it is
    assert check_run_inputs(_cfg(), None, executor=executor) is executor


def test_a_resume_of_a_folder_without_a_run_does_not_create_the_folder(tmp_path):
    typo = tmp_path / "no-such-run"
    with pytest.raises(InputError, match="holds no run to resume"):
        check_run_inputs(_cfg(), typo, resume=True)
    assert not typo.exists()


def test_a_resume_of_another_grid_is_refused_before_the_dask_cluster_starts(tmp_path, monkeypatch):
    pytest.importorskip("distributed")
    from bench.run.executors.dask import DaskExecutor

    started = []
    monkeypatch.setattr(DaskExecutor, "connect", lambda self: started.append(self) or self)
    out = tmp_path / "run"
    out.mkdir()
    (out / "config.json").write_text(json.dumps(_cfg(n=24).to_dict()))
    with pytest.raises(InputError, match="the config differs"):
        run_grid(_cfg(n=16), out, resume=True, executor=ExecutorSpec("dask", workers=1), progress=False)
    assert started == [] and not (out / "cells").exists()


def test_the_command_line_checks_a_run_once(tmp_path, monkeypatch, capsys):
    calls = []
    real = bench.run.inputs.check_run_inputs

    def counted(*args, **kwargs):
        calls.append(args[1])
        return real(*args, **kwargs)

    monkeypatch.setattr(bench.run.inputs, "check_run_inputs", counted)     # the command line's --dry-run
    monkeypatch.setattr(bench.run.runner, "check_run_inputs", counted)     # run_grid
    config = tmp_path / "g.toml"
    config.write_text(GRID)
    out = tmp_path / "o"
    assert main(["run", "--config", str(config), "--out", str(out), "--dry-run"]) == 0
    assert calls == [None] and not out.exists()
    assert main(["run", "--config", str(config), "--out", str(out), "--jobs", "1", "--no-report"]) == 0
    assert calls == [None, out] and "1 ok" in capsys.readouterr().out
