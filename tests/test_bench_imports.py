"""bench/imports.py: a plug-in module that ends its process at import (``os._exit``, a crash) is named in one
line, exit 2, by every command that imports plug-ins — it used to end the command silently with exit code 0."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.imports import probe_imports
from phantoms import InputError

REPO = Path(__file__).resolve().parent.parent
MODULES = {"ends_zero": "import os\nos._exit(0)\n",
           "ends_segv": "import os, signal\nos.kill(os.getpid(), signal.SIGSEGV)\n",
           "raises": "raise RuntimeError('the real import reports this one')\n",
           "fine": "VALUE = 1\n"}


@pytest.fixture()
def modules(modules_on_path):
    return modules_on_path(MODULES)


@pytest.mark.parametrize("module, how", [("ends_zero", "exit code 0"), ("ends_segv", "signal SIGSEGV")])
def test_a_module_ending_its_process_at_import_is_named(modules, module, how):
    with pytest.raises(InputError) as err:
        probe_imports(["json", "fine", module, "raises"])
    assert str(err.value) == (f"cannot import module {module!r}: it ended the process at import ({how}; a plug-in "
                              "module must not exit)")
    assert module not in sys.modules                     # only the child imported it


def test_modules_that_import_or_raise_pass_the_probe(modules):
    probe_imports(["json", "fine", "raises"])           # a raise is the real import's to report, naming it
    probe_imports([])
    assert "fine" not in sys.modules


@pytest.mark.parametrize("command", [["methods"], ["check-method", "marching_cubes"],
                                     ["run", "--quick", "--dry-run"]])
def test_every_command_names_it_on_one_line(modules, tmp_path, command):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(modules), str(REPO)]), PYTHONWARNINGS="ignore")
    out = tmp_path / "run"
    extra = ["--out", str(out)] if command[0] == "run" else []
    r = subprocess.run([sys.executable, "-m", "bench", *command, "--import", "ends_zero", *extra], cwd=REPO,
                       env=env, capture_output=True, text=True, timeout=300)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, (r.returncode, r.stdout, r.stderr)
    assert "cannot import module 'ends_zero': it ended the process at import (exit code 0" in lines[0]
    assert not out.exists()
