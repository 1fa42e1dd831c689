"""Tests of ``bench.run.method_code``: :func:`method_fingerprint` is None for a built-in method, and for a
plug-in a hash of its module's source and its parameters — changed by an edit or a new default, not by
moving the file."""

from __future__ import annotations

import importlib
import shutil
import sys
import textwrap

import pytest

from bench.run.method_code import SUITE_PACKAGES, method_fingerprint
from methods import get_method

PLUGIN = '''
from methods import Method, Param


class Fingerprinted(Method):
    name = "fingerprinted_{tag}"
    description = "a plug-in for the fingerprint tests"
    params = {{"k": Param({default}, "a parameter", float)}}

    def reconstruct(self, volume):
        raise RuntimeError("never run")
'''


def _load(folder, module: str, tag: str, default: float = 1.0, extra: str = ""):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{module}.py").write_text(textwrap.dedent(PLUGIN.format(tag=tag, default=default)) + extra)
    sys.path.insert(0, str(folder))
    try:
        sys.modules.pop(module, None)          # the class's source file is found through its loaded module
        importlib.invalidate_caches()
        return importlib.import_module(module).Fingerprinted
    finally:
        sys.path.remove(str(folder))


@pytest.fixture(autouse=True)
def _forget_the_plugin():
    yield
    sys.modules.pop("fp_plugin", None)


def test_built_in_methods_have_no_fingerprint():
    assert SUITE_PACKAGES == ("geometry", "phantoms", "methods", "bench")
    for name in ("marching_cubes", "shape_gradient", "poisson"):
        assert method_fingerprint(type(get_method(name))) is None


def test_a_plugins_fingerprint_follows_its_code_and_defaults_not_its_place(tmp_path):
    a = method_fingerprint(_load(tmp_path / "a", "fp_plugin", "a"))
    assert set(a) == {"hash", "files"} and len(a["hash"]) == 16
    assert a["files"] == [str((tmp_path / "a" / "fp_plugin.py").resolve())]
    same = method_fingerprint(_load(tmp_path / "a", "fp_plugin", "a"))
    assert same == a
    shutil.copytree(tmp_path / "a", tmp_path / "moved")
    moved = method_fingerprint(_load(tmp_path / "moved", "fp_plugin", "a"))
    assert moved["hash"] == a["hash"] and moved["files"] != a["files"]
    edited = method_fingerprint(_load(tmp_path / "a", "fp_plugin", "a", extra="\n# an edit\n"))
    assert edited["hash"] != a["hash"]
    new_default = method_fingerprint(_load(tmp_path / "b", "fp_plugin", "a", default=2.0))
    assert new_default["hash"] != a["hash"]


def test_a_class_without_a_source_file_is_hashed_by_its_name():
    ns: dict = {}
    exec("from methods import Method\nclass Bare(Method):\n    name = 'bare_fp'\n    params = {}\n", ns)
    ns["Bare"].__module__ = "not_a_module_fp"
    fp = method_fingerprint(ns["Bare"])
    if fp is None:
        pytest.skip("exec'd class resolved to a suite file")
    assert fp["files"] == ["<not_a_module_fp.Bare>"]
