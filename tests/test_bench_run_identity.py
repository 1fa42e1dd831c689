"""bench.run.identity: --resume keeps a folder's grid and code — another config or other code is refused."""

from __future__ import annotations

import json

import pytest

from bench.cli import main
from bench.config import builtin_config
from bench.run.identity import code_identity, code_label, config_differences, config_fingerprint, mixed_code
from bench.run.integrity import seal

GRID = ["--quick", "--phantoms", "sphere", "--noise", "none", "--n", "16", "--n-samples", "2000",
        "--method", "marching_cubes", "--add-method", "mc_taubin", "--jobs", "2"]


def test_config_differences_name_the_changed_keys_and_ignore_labels():
    a = builtin_config("quick").to_dict()
    b = json.loads(json.dumps(a))
    b["name"], b["description"] = "renamed", "other words"
    assert config_differences(a, b) == [] and config_fingerprint(a) == config_fingerprint(b)
    b["grid"]["phantoms"] = ["sphere"]
    b["metrics"]["n_samples"] = 5
    assert config_differences(a, b) == ["grid.phantoms", "metrics.n_samples"]
    assert config_fingerprint(a) != config_fingerprint(b)


def test_code_identity_and_mixing():
    code = code_identity()
    assert set(code) == {"version", "commit", "dirty", "diff"}
    other = {**code, "commit": "0" * 40, "dirty": False}
    assert mixed_code({"a": {"code": code}}, code) == {}
    assert mixed_code({"a": {"code": code}, "b": {"code": other}}, None) == {code_label(code): 1, "? @ 0000000"
                                                                              if not code["version"] else
                                                                              f"{code['version']} @ 0000000": 1}
    assert "unknown" in code_label(None)


@pytest.fixture
def finished(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", *GRID, "--out", str(out), "--no-report"]) == 0
    capsys.readouterr()
    return out


def test_resume_with_another_config_is_refused_naming_the_keys_and_keeps_the_run(finished, capsys):
    before = {p: p.read_bytes() for p in (finished / "config.json", finished / "results.csv")}
    assert main(["run", *GRID[:9], "--method", "marching_cubes", "--jobs", "2", "--resume", "--out",
                 str(finished), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("error: --resume: the config differs") and "(methods)" in err
    assert main(["run", "--quick", "--resume", "--out", str(finished), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "grid.n" in err and "grid.phantoms" in err and "methods" in err and "metrics.n_samples" in err
    assert {p: p.read_bytes() for p in before} == before      # nothing overwritten, no cell dropped


def test_resume_on_a_folder_without_config_is_refused(tmp_path, capsys):
    typo = tmp_path / "no-such-run"
    assert main(["run", "--resume", "--out", str(typo)]) == 2
    err = capsys.readouterr().err
    assert "holds no run to resume (no config.json" in err and not typo.exists()  # not the paper grid


def test_resume_with_other_code_is_refused_unless_allowed_and_then_stated(finished, capsys):
    cells = sorted((finished / "cells").glob("*.json"))
    rec = json.loads(cells[0].read_text())
    rec["code"] = {"version": "0.0.1", "commit": "f" * 40, "dirty": False, "diff": None}
    cells[0].write_text(json.dumps(seal(rec, cells[0].with_suffix(".npz"))))   # as that code wrote it
    cells[1].unlink()                                          # a cell left to compute with today's code
    assert main(["run", *GRID, "--resume", "--out", str(finished), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "computed by other code" in err and "0.0.1 @ fffffff: 1 cells" in err and "--allow-mixed-code" in err
    assert not cells[1].exists()                               # refused before anything ran
    assert main(["run", *GRID, "--resume", "--allow-mixed-code", "--out", str(finished)]) == 0
    meta = json.loads((finished / "run.json").read_text())
    assert meta["mixed_code"]["0.0.1 @ fffffff"] == 1 and meta["sessions"][-1]["allow_mixed_code"] is True
    page = (finished / "index.html").read_text()
    assert "Mixed code" in page and "0.0.1 @ fffffff: 1 cells" in page
    assert json.loads(cells[1].read_text())["code"] == code_identity()   # the new cell records its code
