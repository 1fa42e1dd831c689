"""Tests of ``methods.registry``: :func:`import_plugins` and entry points that exit or fail at import (one line
naming the module, or a warning — never the end of the command), and the names a plug-in may take
(:func:`register_method`: a built-in's refused unless ``replace=True``, a taken one replaced with a warning; an
entry point named as a built-in not used)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parent.parent


# ----------------------------------------------------------------- a plug-in module that exits at import
EXITS_AT_IMPORT = {"exits_zero": "import sys\nsys.exit(0)\n",
                   "exits_msg": "raise SystemExit('bye from the plug-in')\n",
                   "fails_two_lines": "raise RuntimeError('first line\\nsecond line')\n"}


@pytest.fixture()
def exiting_modules(modules_on_path):
    return modules_on_path(EXITS_AT_IMPORT)


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
    from methods import registry

    info = exiting_modules / "exits-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: exits\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[levelset_bench.methods]\nexits = exits_zero:Nope\n")
    monkeypatch.setattr(registry, "_ENTRY_POINTS", {})
    with pytest.warns(UserWarning, match=r"'exits' \(exits_zero:Nope\) failed to load: it called sys.exit\(0\)"):
        methods = available_methods()
    assert "marching_cubes" in methods and "exits" not in methods


# ----------------------------------------------------------------- a plug-in taking a name that is already taken
def _named(name: str, module: str = "my_plugin"):
    from methods import Method

    return type("Taken", (Method,), {"name": name, "__module__": module})


def test_registering_a_builtins_name_is_refused_naming_both_unless_replace(monkeypatch):
    from methods import available_methods, register_method
    from methods import registry
    from phantoms import InputError

    monkeypatch.setattr(registry, "_REGISTERED", dict(registry._REGISTERED))
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
    from methods import registry

    monkeypatch.setattr(registry, "_REGISTERED", dict(registry._REGISTERED))
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
    from methods import registry

    monkeypatch.setattr(registry, "_ENTRY_POINTS", {})
    with pytest.warns(UserWarning, match=r"plug-in method 'shadow' \(shadow_mc:ShadowMC\) is not used: its name "
                                         r"'marching_cubes' is the built-in methods.marching_cubes:MarchingCubes"):
        methods = available_methods()
    assert methods["marching_cubes"].__module__ == "methods.marching_cubes"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(shadowing_plugin), str(REPO)]))
    r = subprocess.run([sys.executable, "-m", "bench", "methods", "marching_cubes"], cwd=REPO, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "class: methods.marching_cubes:MarchingCubes" in r.stdout, r.stderr
    assert "note: plug-in method 'shadow' (shadow_mc:ShadowMC) is not used" in r.stdout
