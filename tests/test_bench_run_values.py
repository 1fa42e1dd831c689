"""Tests of ``bench.run.values``: :func:`plain` (JSON-able values), :func:`cap_text`, :func:`cap_tail` and
:func:`error_text` (one capped line per error)."""

from __future__ import annotations

import json
import math

import numpy as np

from bench.run.values import MAX_MESSAGE, cap_tail, cap_text, error_text, plain


def test_plain_turns_numpy_and_containers_into_json_values():
    out = plain({1: np.int64(3), "f": np.float32(0.5), "b": np.bool_(True), "t": (1, np.array([1.0, 2.0])),
                 "n": None, "nan": float("nan"), "big": np.zeros((10, 10)), "obj": object})
    assert out["1"] == 3 and type(out["1"]) is int
    assert out["f"] == 0.5 and type(out["f"]) is float
    assert out["b"] is True and out["t"] == [1, [1.0, 2.0]] and out["n"] is None
    assert math.isnan(out["nan"])                                   # non-finite floats stay floats
    assert out["big"] == "<array shape [10, 10]>"                   # more than 64 elements: a note
    assert out["obj"] == repr(object)
    json.dumps(out)


def test_cap_text_keeps_short_text_and_cuts_long_text_with_a_note():
    assert cap_text("short", 10) == "short"
    long = "x" * 5000
    capped = cap_text(long, 100, where="the log")
    assert capped.startswith("x" * 100) and "5,000 characters; full text in the log" in capped
    assert len(capped) < 200


def test_cap_tail_keeps_the_start_and_the_exception_line():
    tb = "Traceback (most recent call last):\n" + "  frame\n" * 1000 + "ValueError: the last line"
    out = cap_tail(tb, 200)
    assert out.startswith("Traceback") and out.endswith("ValueError: the last line")
    assert "characters; full text in the cell's record" in out and len(out) < 400
    assert cap_tail("short") == "short"


def test_error_text_is_the_type_and_the_first_line_capped():
    assert error_text(ValueError("bad value\nmore detail")) == "ValueError: bad value"
    assert error_text(RuntimeError()) == "RuntimeError"
    long = error_text(RuntimeError("y" * (3 * MAX_MESSAGE)))
    assert long.startswith("RuntimeError: yyy") and len(long) < MAX_MESSAGE + 100
