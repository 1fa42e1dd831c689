"""Tests of ``methods.base``: :class:`Method` (``reconstruct`` abstract), :func:`check_volume`, and the plug-in
contract where a method breaks it: a ``sys.exit()`` inside ``reconstruct`` and ``info`` values of the wrong type
are failures naming the method (and the key) — in ``reconstruct`` and in a grid cell — never an exit 0 without
output, one warning per character or a text in an integer column.  The registry: test_methods_registry.py."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from methods import Method, Reconstruction
from methods.contract import WrongReturnType, as_reconstruction, check_info
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


def test_a_method_without_reconstruct_cannot_be_instantiated_and_with_it_can():
    class Incomplete(Method):
        name = "incomplete_test"

    with pytest.raises(TypeError, match="reconstruct"):
        Incomplete()

    class Complete(Incomplete):
        def reconstruct(self, volume):
            return Reconstruction(trimesh.creation.icosphere(1), {})

    assert isinstance(Complete().reconstruct(None), Reconstruction)


def test_every_builtin_method_is_complete():
    """Each registered built-in implements every abstract hook (none can be instantiated otherwise)."""
    from methods import available_methods

    assert all(not cls.__abstractmethods__ for cls in available_methods().values())


def test_the_package_exports_the_authors_names_and_not_the_suites_calls():
    import methods
    from methods import contract

    assert {"Method", "Param", "Reconstruction", "ReconstructionFailed", "check_volume", "register_method"
            } <= set(methods.__all__)
    internal = {"run_reconstruct", "check_skip", "run_warm_up", "as_reconstruction", "check_info", "WrongReturnType"}
    assert not internal & set(methods.__all__) and internal <= set(contract.__all__)
    assert all(hasattr(methods, name) for name in methods.__all__)
