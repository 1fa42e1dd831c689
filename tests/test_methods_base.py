"""Tests of ``methods.base``: :func:`check_volume`, :func:`register_method` and the names it may take, and the
plug-in contract where a method breaks it: a ``sys.exit()`` inside ``reconstruct`` and
``info`` values of the wrong type are failures naming the method (and the key) — in ``reconstruct`` and in a
grid cell — never an exit 0 without output, one warning per character or a text in an integer column."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from methods import Reconstruction, WrongReturnType, as_reconstruction, check_info
from phantoms import get_phantom, save_volume

REPO = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent


def _bench(*args) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(TESTS), str(REPO)]), PYTHONWARNINGS="ignore")
    return subprocess.run([sys.executable, "-m", "bench", *args], cwd=REPO, env=env, capture_output=True,
                          text=True, timeout=300)


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    return save_volume(tmp_path_factory.mktemp("v") / "sphere.npz", get_phantom("sphere").volume(n=24))


def test_reconstruct_with_a_method_that_calls_sys_exit_fails_naming_it(sphere, tmp_path):
    out = tmp_path / "m.ply"
    r = _bench("reconstruct", str(sphere), "-m", "exiting", "--import", "runner_plugins", "-o", str(out))
    assert r.returncode == 1, (r.returncode, r.stdout, r.stderr)      # a method failure, as a wrong return type
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "'exiting'" in lines[0] and "sys.exit(0)" in lines[0], r.stderr
    assert "Traceback" not in r.stderr and not out.exists()


@pytest.mark.parametrize("key, value, expected", [
    ("warnings", "a string", "a list of str"),
    ("warnings", ["ok", 3], "a list of str"),
    ("iterations", "many", "an int"),
    ("iterations", 2.5, "an int"),
    ("iterations", True, "an int"),
    ("stop_reason", 3, "a str"),
    ("energy_final", "low", "a real number"),
])
def test_info_values_the_suite_reads_are_type_checked_naming_the_key(key, value, expected):
    mesh = trimesh.creation.icosphere(1)
    with pytest.raises(WrongReturnType, match=rf"method 'm' returned info\['{key}'\].*expected {expected}"):
        as_reconstruction(Reconstruction(mesh, {key: value}), "m")


def test_well_typed_info_passes():
    check_info({"iterations": np.int64(3), "warnings": ("a", "b"), "stop_reason": "done", "energy_final": 1,
                "my_own": object(), "stop_message": None}, "m")


def test_reconstruct_refuses_a_string_of_warnings(sphere, tmp_path):
    r = _bench("reconstruct", str(sphere), "-m", "bad_info", "--set", "key=warnings", "--import", "runner_plugins",
               "-o", str(tmp_path / "m.ply"))
    assert r.returncode == 1 and "info['warnings']" in r.stderr and "a list of str" in r.stderr, r.stderr
    assert "warning: a" not in r.stderr           # not one warning line per character


@pytest.mark.heavy   # end to end, ~10 s: run by .ci/run's second pytest
def test_grid_cells_of_such_methods_are_failed_rows_naming_method_and_key(tmp_path):
    cfg = tmp_path / "g.toml"
    cfg.write_text('[grid]\nphantoms = ["sphere"]\nn = [24]\n[run]\nimports = ["runner_plugins"]\n'
                   '[[methods]]\nname = "exiting"\n'
                   '[[methods]]\nname = "bad_info"\nparams = { key = "iterations" }\n'
                   '[[methods]]\nname = "marching_cubes"\n')
    out = tmp_path / "run"
    r = _bench("run", "--config", str(cfg), "--out", str(out), "--jobs", "1", "--no-report")
    assert r.returncode == 0, r.stderr
    with open(out / "results.csv", newline="") as fh:
        rows = {row["method"]: row for row in csv.DictReader(fh)}
    assert rows["marching_cubes"]["status"] == "ok"
    assert rows["exiting"]["status"] == "failed" and "'exiting' called sys.exit(0)" in rows["exiting"]["error"]
    bad = rows["bad_info"]
    assert bad["status"] == "failed" and "info['iterations']" in bad["error"] and bad["iterations"] == ""


def test_check_volume_accepts_a_volume_with_a_surface_and_names_the_method_otherwise():
    import numpy as np

    from methods import check_volume
    from phantoms import InputError, Volume, get_phantom

    check_volume(get_phantom("sphere").volume(n=16), "m")
    with pytest.raises(InputError, match="'m'"):
        check_volume(np.zeros((8, 8, 8)), "m")
    with pytest.raises(InputError, match="'m'"):
        check_volume(Volume(np.ones((8, 8, 8))), "m")


# ----------------------------------------------------------------- a plug-in module that exits at import
EXITS_AT_IMPORT = {"exits_zero": "import sys\nsys.exit(0)\n",
                   "exits_msg": "raise SystemExit('bye from the plug-in')\n",
                   "fails_two_lines": "raise RuntimeError('first line\\nsecond line')\n"}


@pytest.fixture()
def exiting_modules(tmp_path, monkeypatch):
    for name, text in EXITS_AT_IMPORT.items():
        (tmp_path / f"{name}.py").write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


@pytest.mark.parametrize("module, says", [("exits_zero", "it called sys.exit(0) at import"),
                                          ("exits_msg", "it called sys.exit('bye from the plug-in') at import"),
                                          ("fails_two_lines", "first line second line")])
def test_a_module_exiting_or_failing_at_import_is_one_input_error_naming_it(exiting_modules, module, says):
    from methods import import_plugins
    from phantoms import InputError

    with pytest.raises(InputError) as err:
        import_plugins(["json", module])
    assert str(err.value) == f"cannot import module {module!r}: {says}" + (
        " (a plug-in module must not exit)" if module.startswith("exits") else "")


@pytest.mark.parametrize("command", [["methods"], ["run", "--quick", "--dry-run"]])
@pytest.mark.parametrize("module", ["exits_zero", "exits_msg"])
def test_methods_and_run_with_such_a_module_exit_2_on_one_line(exiting_modules, tmp_path, command, module):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(exiting_modules), str(REPO)]), PYTHONWARNINGS="ignore")
    out = tmp_path / "run"
    extra = ["--out", str(out)] if command[0] == "run" else []
    r = subprocess.run([sys.executable, "-m", "bench", *command, "--import", module, *extra], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=300)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, (r.returncode, r.stdout, r.stderr)
    assert lines[0].startswith("error: ") and f"module {module!r}" in lines[0] and "sys.exit(" in lines[0]
    assert not out.exists()


def test_an_entry_point_exiting_at_import_is_a_warning_not_the_end(exiting_modules, monkeypatch):
    from methods import available_methods
    from methods import base as methods_base

    info = exiting_modules / "exits-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: exits\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[levelset_bench.methods]\nexits = exits_zero:Nope\n")
    monkeypatch.setattr(methods_base, "_ENTRY_POINTS", {})
    with pytest.warns(UserWarning, match=r"'exits' \(exits_zero:Nope\) failed to load: it called sys.exit\(0\)"):
        methods = available_methods()
    assert "marching_cubes" in methods and "exits" not in methods


# ----------------------------------------------------------------- a plug-in taking a name that is already taken
def _named(name: str, module: str = "my_plugin"):
    from methods import Method

    return type("Taken", (Method,), {"name": name, "__module__": module})


def test_registering_a_builtins_name_is_refused_naming_both_unless_replace(monkeypatch):
    from methods import available_methods, register_method
    from methods import base as methods_base
    from phantoms import InputError

    monkeypatch.setattr(methods_base, "_REGISTERED", dict(methods_base._REGISTERED))
    with pytest.raises(InputError) as err:
        register_method(_named("marching_cubes"))
    text = str(err.value)
    assert "my_plugin:Taken" in text and "methods.marching_cubes:MarchingCubes" in text and "replace=True" in text
    assert "\n" not in text and available_methods()["marching_cubes"].__module__ == "methods.marching_cubes"
    mine = register_method(replace=True)(_named("marching_cubes"))
    assert available_methods()["marching_cubes"] is mine


def test_registering_a_taken_plugin_name_warns_naming_both_and_a_reload_is_silent(monkeypatch):
    import warnings

    from methods import available_methods, register_method
    from methods import base as methods_base

    monkeypatch.setattr(methods_base, "_REGISTERED", dict(methods_base._REGISTERED))
    register_method(_named("taken_test", "first_plugin"))
    with pytest.warns(UserWarning, match="second_plugin:Taken replaces the one registered by first_plugin:Taken"):
        second = register_method(_named("taken_test", "second_plugin"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = register_method(_named("taken_test", "second_plugin"))     # the module reloaded: no warning
    assert available_methods()["taken_test"] is again and again is not second


@pytest.fixture()
def shadowing_plugin(tmp_path, monkeypatch):
    """An installed (entry-point) plug-in whose class is named as a built-in."""
    (tmp_path / "shadow_mc.py").write_text(
        "from methods import Method\n\nclass ShadowMC(Method):\n    name = 'marching_cubes'\n")
    info = tmp_path / "shadow_mc-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: shadow-mc\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[levelset_bench.methods]\nshadow = shadow_mc:ShadowMC\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    return tmp_path


def test_an_entry_point_named_as_a_builtin_is_not_used_and_says_so(shadowing_plugin, monkeypatch):
    from methods import available_methods
    from methods import base as methods_base

    monkeypatch.setattr(methods_base, "_ENTRY_POINTS", {})
    with pytest.warns(UserWarning, match=r"plug-in method 'shadow' \(shadow_mc:ShadowMC\) is not used: its name "
                                         r"'marching_cubes' is the built-in methods.marching_cubes:MarchingCubes"):
        methods = available_methods()
    assert methods["marching_cubes"].__module__ == "methods.marching_cubes"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(shadowing_plugin), str(REPO)]))
    r = subprocess.run([sys.executable, "-m", "bench", "methods", "marching_cubes"], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "class: methods.marching_cubes:MarchingCubes" in r.stdout, r.stderr
    assert "note: plug-in method 'shadow' (shadow_mc:ShadowMC) is not used" in r.stdout
