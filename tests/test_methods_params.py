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


@pytest.mark.parametrize("default, value, expected", [
    (3, "5", 5), (3, 5.0, 5), (2.5, "4", 4.0), (True, "off", False), ("a", "b", "b")])
def test_a_param_keeps_its_defaults_type_whether_set_or_not(default, value, expected):
    p = Param(default, "doc")
    assert type(p.default) is type(default) and p.type is type(default)
    got = p.convert("m", "k", value)
    assert got == expected and type(got) is type(default)


def test_the_default_goes_through_the_same_conversion_as_a_value():
    import numpy as np

    assert type(Param(np.int64(4), "doc").default) is int         # numpy scalars become Python ones
    assert type(Param(np.float32(0.5), "doc").default) is float
    assert Param(1, "doc", float).default == 1.0 and type(Param(1, "doc", float).default) is float
    assert Param(np.bool_(True), "doc").type is bool
    assert Param((1, 2), "doc").type is object                      # free-form: anything goes through


@pytest.mark.parametrize("make, words", [
    (lambda: Param(None, "doc"), "needs type="),
    (lambda: Param(3.5, "doc", int), "expected int, got 3.5"),
    (lambda: Param(20, "doc", min=0, max=10), "above the maximum 10"),
    (lambda: Param("c", "doc", choices=("a", "b")), "not one of"),
])
def test_a_default_the_param_would_refuse_is_an_error_when_the_class_is_defined(make, words):
    with pytest.raises(TypeError, match=words):
        make()


@pytest.mark.parametrize("default, value, type_name", [(3, 2.5, "int"), (3, "x", "int"), (3, True, "int"),
                                                       (True, 1, "bool"), (True, "maybe", "bool"),
                                                       (2.0, "two", "float"), ("a", 3, "str")])
def test_a_value_of_the_wrong_type_is_one_line_naming_method_parameter_and_type(default, value, type_name):
    with pytest.raises(InputError) as err:
        Param(default, "doc").convert("m", "k", value)
    text = str(err.value)
    assert text == f"method 'm', parameter 'k': expected {type_name}, got {value!r}" and "\n" not in text


def test_a_method_with_an_int_param_gives_an_int_set_or_unset():
    from methods import Method

    class Counting(Method):
        name = "counting_test"
        params = {"n": Param(3, "how many")}

        def reconstruct(self, volume):
            raise NotImplementedError

    assert type(Counting().config["n"]) is int and Counting().config["n"] == 3
    assert type(Counting(n="5").config["n"]) is int and Counting(n=5.0).config["n"] == 5
