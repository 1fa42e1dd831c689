"""The argparse validators (bench.cli.validators): one home for every option's parse-or-explain."""

from __future__ import annotations

import argparse

import pytest

from bench.cli import validators as v
from bench.run.limits import MAX_SECONDS


@pytest.mark.parametrize("parse, text, message", [
    (v.positive_int, "x", "not an integer: 'x'"),
    (v.positive_int, "0", "must be >= 1: '0'"),
    (v.int_at_least(0), "-1", "must be >= 0: '-1'"),
    (v.int_between(12, 128), "129", "must be in [12, 128]: '129'"),
    (v.nonneg_float, "nan", "must be a finite number >= 0: 'nan'"),
    (v.nonneg_float, "inf", "must be a finite number >= 0: 'inf'"),
    (v.nonneg_float, "-0.5", "must be a finite number >= 0: '-0.5'"),
    (v.finite_float, "-inf", "must be finite: '-inf'"),
    (v.finite_float, "a", "not a number: 'a'"),
    (v.int_list, "1,a", "expected comma-separated integers: '1,a'"),
    (v.case_timeout, "-1", f"must be between 0 (no limit) and {MAX_SECONDS:.0f}: '-1'"),
])
def test_a_bad_value_is_refused_with_the_text_quoted(parse, text, message):
    with pytest.raises(argparse.ArgumentTypeError, match="^" + message.replace("[", r"\[").replace("(", r"\(")
                       .replace(")", r"\)").replace("+", r"\+") + "$"):
        parse(text)


def test_a_good_value_is_returned_parsed():
    assert v.positive_int("3") == 3 and v.int_at_least(0)("0") == 0 and v.int_between(12, 128)("12") == 12
    assert v.nonneg_float("0") == 0.0 and v.finite_float("-2.5") == -2.5 and v.case_timeout("0") == 0.0
    assert v.int_list("24, 48,") == [24, 48]


def test_the_cli_modules_keep_no_copy_of_a_validator():
    import inspect

    from bench.cli import check, perf, run, volumes

    for mod in (check, perf, run, volumes):
        assert "ArgumentTypeError" not in inspect.getsource(mod)
