"""The shape gradient's size limits: few parameters, each documented in a line or two (the reasons live in
docs/METHOD.md)."""

from __future__ import annotations

from methods.shape_gradient import ShapeGradient

#: the most parameters the method may have (every one a knob some config, preset, test or doc workflow turns)
MAX_PARAMETERS = 35
#: a parameter's doc says what it does and its unit, in a line or two of ``python -m bench methods``
MAX_DOC_CHARS = 160


def test_the_method_has_at_most_35_parameters():
    assert len(ShapeGradient.params) <= MAX_PARAMETERS, sorted(ShapeGradient.params)


def test_each_parameter_doc_is_a_line_or_two():
    long = {k: len(p.doc) for k, p in ShapeGradient.params.items() if len(p.doc) > MAX_DOC_CHARS}
    assert not long, long


def test_the_start_choice_settings_are_not_parameters():
    from methods.shape_gradient.choose import USUAL_START

    assert not set(USUAL_START) & set(ShapeGradient.params)
