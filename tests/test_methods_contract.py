"""Tests of ``methods.contract``'s hooks: :func:`check_skip` turns a method's ``skip_reason`` into
:class:`MethodSkipped` (one line, pickled across processes) or a :class:`WrongReturnType`, and
:func:`run_warm_up` calls ``warm_up``; the defaults take every volume and do nothing."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import hook_plugins
from methods import Method, MethodSkipped, get_method
from methods.contract import WrongReturnType, check_skip, run_reconstruct, run_warm_up
from phantoms import InputError, get_phantom


@pytest.fixture(scope="module")
def sphere():
    return get_phantom("sphere").volume(n=24)


def test_the_default_hooks_take_every_volume_and_do_nothing(sphere):
    method = get_method("marching_cubes")
    assert type(method).skip_reason is Method.skip_reason and type(method).warm_up is Method.warm_up
    check_skip(method, sphere)
    run_warm_up(method)


def test_a_reason_is_a_one_line_method_skipped_naming_the_method(sphere):
    with pytest.raises(MethodSkipped) as err:
        check_skip(get_method("picky_mc"), sphere)
    exc = err.value
    assert isinstance(exc, InputError) and exc.method == "picky_mc"
    assert exc.reason == "the grid has 24 points per axis, fewer than the 30 it needs"
    assert str(exc) == f"method 'picky_mc' skips this input: {exc.reason}"
    again = pickle.loads(pickle.dumps(exc))
    assert type(again) is MethodSkipped and str(again) == str(exc) and again.reason == exc.reason
    check_skip(get_method("picky_mc", min_n=24), sphere)                  # None: it takes the volume


@pytest.mark.parametrize("hook, error", [("skip_type", WrongReturnType), ("skip_raises", ValueError)])
def test_a_skip_reason_that_breaks_its_contract_is_not_a_skip(sphere, hook, error):
    with pytest.raises(error) as err:
        check_skip(get_method("bad_hooks", hook=hook), sphere)
    assert not isinstance(err.value, MethodSkipped)
    if error is WrongReturnType:
        assert "skip_reason returned 3" in str(err.value)


def test_run_warm_up_calls_the_hook_and_names_a_sys_exit(sphere, monkeypatch):
    monkeypatch.setattr(hook_plugins, "_WARMED", [])
    run_warm_up(get_method("warm_mc"))
    assert hook_plugins._WARMED == [True]
    monkeypatch.setattr(hook_plugins.WarmMC, "warm_up", lambda self: exit(3))
    with pytest.raises(WrongReturnType, match=r"'warm_mc' called sys.exit\(3\) in warm_up"):
        run_warm_up(get_method("warm_mc"))


class _Writes(Method):
    """Marching cubes after changing its input in the way ``how`` names (a 2 h shift of the level set)."""

    name = "writes_input"
    description = "writes to its input volume"
    params: dict = {}

    def __init__(self, how: str) -> None:
        super().__init__()
        self.how = how

    def reconstruct(self, volume):
        h = volume.h
        if self.how == "flag":                       # turns the read-only flag back on, then writes
            volume.values.flags.writeable = True
            volume.values += 2 * h
        elif self.how == "base":                     # writes through the view's base array
            volume.values.base[...] += 2 * h
        elif self.how == "rebind":
            volume.values = volume.values + 2 * h
        elif self.how == "origin":
            volume.origin += 2 * h
        elif self.how == "spacing":
            volume.spacing *= 1.25
        return get_method("marching_cubes").reconstruct(volume)


@pytest.mark.parametrize("how, part", [("flag", "values"), ("base", "values"), ("rebind", "values"),
                                       ("origin", "origin"), ("spacing", "spacing")])
def test_a_method_that_changes_its_input_volume_is_a_wrong_return_naming_what(how, part):
    """The read-only flag stops a careless write; a method that gets round it is still caught, so its mesh is
    never checked against a φ it made up."""
    volume = get_phantom("sphere").volume(n=16)
    with pytest.raises(WrongReturnType, match=rf"method 'writes_input' changed its input volume \({part}\): "
                                              "the volume is read-only"):
        run_reconstruct(_Writes(how), volume)


def test_a_method_that_only_reads_its_input_passes_the_fingerprint(sphere):
    assert run_reconstruct(get_method("marching_cubes"), sphere).mesh.is_watertight


def test_grids_a_method_wrote_into_are_rebuilt_before_the_suite_reads_them():
    """The cached interpolation grids are derived and writeable: a method that shifts φ there (its mesh still
    right) must not make the suite's checks read the shifted φ — they are dropped when the method returns."""
    volume = get_phantom("sphere").volume(n=16)
    exact = np.array(volume.channels(1))

    class _ShiftsGrids(_Writes):
        def reconstruct(self, vol):
            vol.channels(1)[..., 0] += 2 * vol.h
            return get_method("marching_cubes").reconstruct(vol)

    run_reconstruct(_ShiftsGrids("grids"), volume)
    np.testing.assert_array_equal(volume.channels(1), exact)
