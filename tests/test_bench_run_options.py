"""bench.run.options.RunOptions: run_grid's options as one frozen value; keywords override its fields, an unknown
one is a TypeError before anything is written."""

from __future__ import annotations

import dataclasses
import json

import pytest

from bench.config import builtin_config
from bench.run import RunOptions, run_grid
from bench.run.contracts import CellResult


class _InstantExecutor:
    """A made-up ``ok`` row per cell, at once (the options are under test, not the cells)."""

    def run(self, cells, on_start, on_result) -> None:
        for i, cell in enumerate(sorted(cells, key=lambda c: c.cell_id)):
            on_start(cell)
            on_result(cell, CellResult(row={"cell_id": cell.cell_id, "phantom": cell.phantom, "method": cell.method,
                                            "label": cell.label, "hausdorff_h": 0.5 + i / 8, "status": "ok",
                                            "error": ""}))


def _cfg():
    cfg = builtin_config("quick")
    cfg.n = [16]
    return cfg


def _session(out) -> dict:
    return json.loads((out / "run.json").read_text())["sessions"][-1]


def test_options_and_keywords_run_the_same_grid(tmp_path):
    opts = RunOptions(jobs=3, progress=False, argv=["run", "--quick"], executor=_InstantExecutor())
    a = run_grid(_cfg(), tmp_path / "a", opts)
    b = run_grid(_cfg(), tmp_path / "b", jobs=3, progress=False, argv=["run", "--quick"], executor=_InstantExecutor())
    assert (a.ok, a.ran, b.ok, b.ran) == (12, 12, 12, 12)
    assert (tmp_path / "a" / "results.csv").read_bytes() == (tmp_path / "b" / "results.csv").read_bytes()
    for out in (tmp_path / "a", tmp_path / "b"):
        assert (_session(out)["argv"], _session(out)["jobs"]) == (["run", "--quick"], 3)


def test_keywords_override_the_options_and_an_unknown_one_is_refused_before_anything_is_written(tmp_path):
    opts = RunOptions(jobs=3, progress=False, argv=["first"], executor=_InstantExecutor())
    run_grid(_cfg(), tmp_path / "run", opts, jobs=1, argv=["second"])
    assert (_session(tmp_path / "run")["argv"], _session(tmp_path / "run")["jobs"]) == (["second"], 1)
    assert opts.jobs == 3                                      # the options themselves are unchanged
    with pytest.raises(TypeError, match="jbos"):
        run_grid(_cfg(), tmp_path / "typo", opts, jbos=2)
    assert not (tmp_path / "typo").exists()
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.jobs = 2


def test_the_input_checks_are_every_option_check_run_inputs_takes():
    """RunOptions.input_checks() hands check_run_inputs each of its keyword arguments, with the option's value."""
    import inspect

    from bench.run.inputs import check_run_inputs

    opts = RunOptions(jobs=3, resume=True, timeout=7.0, memory_gb=2.5, allow_mixed_code=True)
    checks = opts.input_checks()
    keywords = {n for n, p in inspect.signature(check_run_inputs).parameters.items() if p.kind is p.KEYWORD_ONLY}
    assert set(checks) == keywords
    assert (checks["jobs"], checks["resume"], checks["timeout"], checks["memory_gb"]) == (3, True, 7.0, 2.5)
