"""Tests of ``methods.params``: :class:`Param` converts command-line strings to its type and checks choices and
bounds, naming the method and the parameter; None as the default reads as "auto"."""

from __future__ import annotations

import pytest

from methods.params import Param
from phantoms import InputError


def test_param_converts_command_line_strings_and_checks_choices_and_bounds():
    p = Param(1.0, "a weight", float, min=0.0, max=10.0)
    assert p.convert("m", "w", "2.5") == 2.5 and p.convert("m", "w", 3) == 3.0
    for bad in ("-1", 11, "lots"):
        with pytest.raises(InputError, match="method 'm', parameter 'w'"):
            p.convert("m", "w", bad)
    c = Param("lewiner", "variant", str, choices=("lewiner", "lorensen"))
    assert c.convert("m", "v", "lorensen") == "lorensen"
    with pytest.raises(InputError, match="'v'"):
        c.convert("m", "v", "other")
    b = Param(True, "a switch", bool)
    assert b.convert("m", "b", "false") is False and b.convert("m", "b", "true") is True
    auto = Param(None, "auto by default", int, min=2)
    assert auto.convert("m", "a", "auto") is None and auto.convert("m", "a", "7") == 7


@pytest.mark.parametrize("value", [float("inf"), "inf", float("-inf"), 1e400, "1e400", float("nan")])
def test_a_non_finite_integer_parameter_is_an_input_error_not_an_overflow(value):
    from methods import get_method
    from phantoms import InputError

    with pytest.raises(InputError, match="parameter 'max_iter': expected int"):
        get_method("shape_gradient", max_iter=value)
