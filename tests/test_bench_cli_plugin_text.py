"""A plug-in's text reaches the terminal shown, never obeyed (issue 40, item 13): ``methods`` and
``check-method`` print plug-in names, descriptions, classes and parameter docs through
:func:`bench.terminal.printable`, and what a method writes on its own stdout / stderr while ``check-method`` runs
it in a child process is captured — at most a few KB of it shown, escaped, with how much was cut.  ``info``
escapes a file name holding ESC.  The hostile plug-in is written here, into the test's own folder."""

from __future__ import annotations

import re
import sys
import textwrap

import pytest

from bench.cli import main
from methods import registry
from phantoms import get_phantom, save_volume

#: what a terminal obeys: ESC, BEL, C1 controls, bidirectional overrides
RAW = re.compile(r"[\x07\x1b\x9b\u202e]")

PLUGIN = r'''
import os
import sys

from methods import Method, Param, get_method, register_method


@register_method
class Shouting(Method):
    name = "shouting\x1b[2J"
    description = "clears the screen \x1b[2J, retitles it \x1b]0;pwned\x07, rings \x07 and turns \u202ethis around"
    params = {"k\x1b[31m": Param(1.0, "a doc in \x1b[31mred\x1b[0m \u202e", float, min=0.0)}

    def reconstruct(self, volume):
        print("\x1b]0;stdout title\x07" + "o" * 6000)              # sys.stdout
        sys.stderr.write("\x1b[2J stderr line\n")                  # sys.stderr
        os.write(1, b"\x1b[31m fd 1 from C\n")                     # the file descriptors themselves
        os.write(2, b"\x07 fd 2 from C\n")
        return get_method("marching_cubes").reconstruct(volume)
'''


@pytest.fixture
def shouting(tmp_path, monkeypatch):
    """The plug-in module above, importable as ``shouting_plugin``; the registry restored afterwards."""
    (tmp_path / "shouting_plugin.py").write_text(textwrap.dedent(PLUGIN))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_REGISTERED", dict(registry._REGISTERED))
    monkeypatch.delitem(sys.modules, "shouting_plugin", raising=False)
    return "shouting\x1b[2J"


def test_methods_shows_a_plugins_control_characters_escaped(shouting, capsys):
    assert main(["methods", "--import", "shouting_plugin"]) == 0
    out = capsys.readouterr().out
    assert not RAW.search(out), [ln for ln in out.splitlines() if RAW.search(ln)]
    assert "shouting\\x1b[2J — clears the screen \\x1b[2J, retitles it \\x1b]0;pwned\\x07" in out
    assert "turns \\u202ethis around" in out
    assert "k\\x1b[31m" in out and "a doc in \\x1b[31mred\\x1b[0m \\u202e" in out


def test_methods_for_one_plugin_by_name(shouting, capsys):
    assert main(["methods", shouting, "--import", "shouting_plugin"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("shouting\\x1b[2J — ") and not RAW.search(out)


def test_check_method_captures_the_methods_own_output_and_shows_its_head_escaped(shouting, capfd):
    code = main(["check-method", shouting, "--import", "shouting_plugin", "--case", "sphere", "--timeout", "60"])
    out, err = capfd.readouterr()
    assert code == 0, out
    assert err == ""                                   # nothing of the method's reached the terminal's stderr
    assert not RAW.search(out), [ln for ln in out.splitlines() if RAW.search(ln)][:3]
    assert out.startswith("check-method shouting\\x1b[2J (k\\x1b[31m=1.0)")
    m = re.search(r"output: the method wrote (\d+) bytes on stdout / stderr; the first 4096 shown, (\d+) cut:", out)
    assert m, out
    total = 6000 + len("\x1b]0;stdout title\x07\n") + len("\x1b[2J stderr line\n") + len(
        b"\x1b[31m fd 1 from C\n") + len(b"\x07 fd 2 from C\n")
    assert int(m.group(1)) == total and int(m.group(2)) == total - 4096
    assert "| \\x1b]0;stdout title\\x07oooo" in out
    assert len(out) < 4096 * 2 + 2000                  # a few KB, not all of it
    assert out.strip().splitlines()[-1].startswith("ok: 1 cases honour the method contract")


def test_check_method_without_a_child_process_captures_the_output_too(shouting, capfd):
    """``--timeout 0`` runs the cases in this process: the method's prints are captured all the same."""
    code = main(["check-method", shouting, "--import", "shouting_plugin", "--case", "sphere", "--timeout", "0"])
    out, err = capfd.readouterr()
    assert code == 0, out
    assert err == "" and not RAW.search(out)
    assert re.search(r"output: the method wrote \d+ bytes on stdout / stderr", out)
    assert "| \\x1b]0;stdout title\\x07oooo" in out


def test_reconstruct_shows_the_methods_own_output_escaped(shouting, capfd, tmp_path):
    save_volume(tmp_path / "s.npz", get_phantom("sphere").volume(n=24))
    code = main(["reconstruct", "--method", shouting, str(tmp_path / "s.npz"), "-o", str(tmp_path / "m.ply"),
                 "--import", "shouting_plugin"])
    out, err = capfd.readouterr()
    assert code == 0, err
    assert not RAW.search(out) and not RAW.search(err), [ln for ln in err.splitlines() if RAW.search(ln)][:3]
    assert "wrote" in err and "bytes on stdout / stderr (control characters escaped, first 4096 shown)" in err
    assert "| \\x1b]0;stdout title\\x07oooo" in err and len(err) < 4096 * 2 + 2000


def test_a_quiet_method_prints_no_output_section(capsys):
    assert main(["check-method", "marching_cubes", "--case", "sphere", "--timeout", "60"]) == 0
    assert "output:" not in capsys.readouterr().out


def test_info_escapes_a_file_name_holding_esc(tmp_path, capsys):
    path = tmp_path / "s\x1b]0;pwned\x07.npz"
    save_volume(path, get_phantom("sphere").volume(n=16))
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert "s\\x1b]0;pwned\\x07.npz" in out and not RAW.search(out)
    assert main(["info", str(tmp_path / "missing\x1b[2J.npz")]) == 2
    err = capsys.readouterr().err
    assert "missing\\x1b[2J.npz" in err and not RAW.search(err)
