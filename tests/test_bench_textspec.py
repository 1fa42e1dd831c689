"""Tests of ``bench.textspec``: :func:`parse_value` (TOML values, else the text) and :func:`split_top`
(commas outside brackets)."""

from __future__ import annotations

import pytest

from bench.textspec import parse_value, split_top


@pytest.mark.parametrize("text, value", [("3", 3), ("2.5", 2.5), ("true", True), ("[1, 50]", [1, 50]),
                                         ('"a,b"', "a,b"), ("lewiner", "lewiner"), ("1e-3", 1e-3),
                                         ("{a = 1}", {"a": 1}), ("", "")])
def test_parse_value(text, value):
    assert parse_value(text) == value
    assert type(parse_value(text)) is type(value)


def test_split_top_keeps_brackets_together_and_drops_empty_items():
    assert split_top("a=1, snapshots=[1,50],b={x=1,y=2}") == ["a=1", "snapshots=[1,50]", "b={x=1,y=2}"]
    assert split_top(" a , ,b,") == ["a", "b"]
    assert split_top("") == []
    assert split_top("x=[[1,2],[3]],y") == ["x=[[1,2],[3]]", "y"]
