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


# ---------------------------------------------------------------------------------------------- plug-in code
PLUGIN = '''
from methods import Method, Param, Reconstruction, get_method, register_method


@register_method
class Marker(Method):
    name = "marker"
    description = "marching cubes that reports its parameter as the iteration count"
    params = {"mark": Param(1, "the iteration count reported", int)}

    def reconstruct(self, volume):
        rec = get_method("marching_cubes").reconstruct(volume)
        return Reconstruction(rec.mesh, {"iterations": self.config["mark"]})
'''


def _import_file(path, monkeypatch):
    import importlib.util
    import sys

    spec = importlib.util.spec_from_file_location(f"fp_{path.stem}", path)
    mod = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, mod)         # where inspect finds a class's file
    spec.loader.exec_module(mod)
    return mod


def test_method_fingerprint_hashes_the_plugin_files_and_params_not_the_builtins(tmp_path, monkeypatch):
    from methods import Method, Param, available_methods
    from methods.registry import BUILTIN_METHODS

    from bench.run.method_code import method_fingerprint

    registry = available_methods()
    assert all(method_fingerprint(registry[name]) is None for name in BUILTIN_METHODS)   # the suite's identity
    base = tmp_path / "base_plugin.py"
    base.write_text("from methods import Method, Param\n\nclass Base(Method):\n    name = 'b'\n"
                    "    params = {'k': Param(1.0, 'k')}\n")
    child = tmp_path / "child_plugin.py"
    child.write_text("class Child:\n    pass\n")
    Base = _import_file(base, monkeypatch).Base
    fp = method_fingerprint(Base)
    assert fp["files"] == [str(base.resolve())] and len(fp["hash"]) == 16
    Child = type("Child", (Base,), {"__module__": _import_file(child, monkeypatch).__name__, "name": "c"})
    assert method_fingerprint(Child)["files"] == [str(child.resolve()), str(base.resolve())]  # its bases too
    assert method_fingerprint(Child)["hash"] != fp["hash"]
    base.write_text(base.read_text() + "# a comment is a change of the file\n")
    assert method_fingerprint(Base)["hash"] != fp["hash"]                 # the bytes on disk count
    other = type("Base", (Method,), {"__module__": Base.__module__, "params": {"k": Param(2.0, "k")}})
    assert method_fingerprint(other)["hash"] != method_fingerprint(Base)["hash"]   # the defaults count
    nofile = type("Loose", (Method,), {"__module__": "__no_such_module__"})
    assert method_fingerprint(nofile)["files"] == ["<__no_such_module__.Loose>"]


def test_changed_methods_compares_the_stored_and_current_method_code():
    from bench.run.identity import changed_methods

    from bench.run import Cell

    fp = {"hash": "1" * 16, "files": ["/x/p.py"]}
    base = dict(phantom="sphere", variant="sdf", n=16, extent=2.5, noise="none", snr_requested=None, seed=0,
                label="x", params={}, n_samples=100)
    cells = [Cell(**base, cell_id="a", method="p", method_code=fp),
             Cell(**base, cell_id="b", method="p", method_code=fp), Cell(**base, cell_id="c", method="marching_cubes")]
    same = {c.cell_id: {"cell": c.to_dict()} for c in cells}
    assert changed_methods(same, cells) == {}
    moved = {**same, "a": {"cell": {**cells[0].to_dict(), "method_code": {**fp, "files": ["/y/p.py"]}}}}
    assert changed_methods(moved, cells) == {}                            # the same code in another folder
    old = {**same, "a": {"cell": {**cells[0].to_dict(), "method_code": {**fp, "hash": "2" * 16}}},
           "b": {"cell": {k: v for k, v in cells[1].to_dict().items() if k != "method_code"}}}
    assert changed_methods(old, cells) == {"p": {"cells": ["a", "b"], "files": ["/x/p.py"], "unknown": True}}


def _bench(tmp_path, *args):
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parent.parent
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path / "plugins"), str(repo)]
                                        + [p for p in [env.get("PYTHONPATH")] if p])
    env["PYTHONWARNINGS"] = "ignore"
    return subprocess.run([sys.executable, "-m", "bench", "run", "--quick", "--phantoms", "sphere", "--noise",
                           "none", "--n", "16,20", "--n-samples", "2000", "--method", "marker", "--add-method",
                           "marching_cubes", "--import", "marker_plugin", "--jobs", "2", "--no-report", "--out",
                           str(tmp_path / "run"), *args], cwd=repo, env=env, capture_output=True, text=True,
                          timeout=300)


def _iterations(out) -> list[tuple[str, str, str]]:
    import csv

    with open(out / "results.csv", newline="") as fh:
        return [(r["cell_id"], r["label"], r["iterations"]) for r in csv.DictReader(fh)]


@pytest.mark.heavy
def test_resume_reruns_the_cells_of_a_changed_plugin_and_says_so(tmp_path):
    plugin = tmp_path / "plugins" / "marker_plugin.py"
    plugin.parent.mkdir()
    plugin.write_text(PLUGIN)
    out = tmp_path / "run"
    first = _bench(tmp_path)
    assert first.returncode == 0, first.stderr
    before = _iterations(out)
    assert sorted(it for _, label, it in before if label == "marker") == ["1", "1"]
    marker = next((out / "cells").glob("*marker*.json"))
    code = json.loads(marker.read_text())["cell"]["method_code"]
    assert code["files"] == [str(plugin.resolve())]
    mc = {p.name: p.read_bytes() for p in (out / "cells").glob("*marching_cubes*")}

    same = _bench(tmp_path, "--resume")                           # nothing changed: nothing rerun
    assert same.returncode == 0, same.stderr
    assert "(0 run, 4 already done)" in same.stdout and "note: method" not in same.stderr

    plugin.write_text(PLUGIN.replace("Param(1,", "Param(7,"))    # the plug-in's default changes
    changed = _bench(tmp_path, "--resume")
    assert changed.returncode == 0, changed.stderr
    assert (f"note: method 'marker' changed since its cells were computed (plug-in {plugin.resolve()}); "
            "rerunning its 2 cells") in changed.stderr
    assert "(2 run, 2 already done)" in changed.stdout
    after = _iterations(out)
    assert [cid for cid, _, _ in after] == [cid for cid, _, _ in before]       # the same cells, once each
    assert sorted(it for _, label, it in after if label == "marker") == ["7", "7"]
    assert {p.name: p.read_bytes() for p in (out / "cells").glob("*marching_cubes*")} == mc   # built-in kept
    assert len(list((out / "cells").glob("*.json"))) == 4
    meta = json.loads((out / "run.json").read_text())
    assert meta["sessions"][-1]["methods_changed"] == {"marker": 2}
    assert json.loads(marker.read_text())["cell"]["method_code"]["hash"] != code["hash"]   # the new code's
