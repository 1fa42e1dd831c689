"""Helpers shared by the tests of the methods whose package is optional (cgal_mesher, vdb); not collected.

* :func:`check_missing_package` – with the package hidden (a ``None`` entry in ``sys.modules``: ``import``
  raises ImportError and ``importlib.util.find_spec`` answers None, as when it is not installed), the
  method is listed as unavailable with the install command, ``reconstruct`` fails in one line naming it and
  the command line exits 2 without a traceback;
* :func:`validity` – the suite's own validity reasons for a mesh (``bench.metrics.validity.check_mesh``).
"""

from __future__ import annotations

import sys

import pytest

from bench.metrics.validity import check_mesh
from methods import get_method
from phantoms import InputError, save_volume

from _peers_common import volume


def validity(mesh, vol) -> list[str]:
    return check_mesh(mesh, vol)


def check_missing_package(monkeypatch, tmp_path, capsys, method: str, module: str, install: str) -> None:
    for name in [m for m in sys.modules if m == module or m.startswith(module + ".")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, module, None)
    from bench.cli import main

    assert main(["methods", method]) == 0
    out = capsys.readouterr().out
    assert f"unavailable: method {method!r} needs {module}, which is not installed: {install}" in out
    with pytest.raises(InputError) as exc:
        get_method(method).reconstruct(volume("sphere", 24))
    msg = str(exc.value)
    assert "\n" not in msg and method in msg and install in msg
    path = tmp_path / "sphere.npz"
    save_volume(path, volume("sphere", 24))
    assert main(["reconstruct", str(path), "-m", method, "-o", str(tmp_path / "out.ply")]) == 2
    err = capsys.readouterr().err
    assert install in err and "Traceback" not in err


def check_bad_input(method: str, **params) -> None:
    """No zero crossing, an open level set, not a volume, an out-of-range parameter: one-line InputErrors
    naming the method."""
    from phantoms import get_phantom

    sphere = volume("sphere", 24)
    for values in (sphere.values * 0 + 0.7, sphere.values * 0 - 0.7):
        with pytest.raises(InputError, match=rf"method '{method}'.*no zero crossing"):
            get_method(method).reconstruct(sphere.with_values(values))
    with pytest.raises(InputError, match=rf"method '{method}'.*open"):
        get_method(method).reconstruct(get_phantom("sphere").volume(n=24, extent=0.8))
    with pytest.raises(InputError, match=rf"method '{method}'.*expected a phantoms.Volume"):
        get_method(method).reconstruct(sphere.values)
    for key, value in params.items():
        with pytest.raises(InputError, match=rf"method '{method}'.*{key}") as exc:
            get_method(method, **{key: value})
        assert "\n" not in str(exc.value)
