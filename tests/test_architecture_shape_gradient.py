"""The shape gradient's size limits: few parameters, each documented in a line or two (the reasons live in
docs/METHOD.md); ``flow.step`` short enough to read as the paper's four steps; a flow holding few attributes."""

from __future__ import annotations

import ast
import inspect
import textwrap

from methods.shape_gradient import ShapeGradient, ShapeGradientFlow

#: the most parameters the method may have (every one a knob some config, preset, test or doc workflow turns)
MAX_PARAMETERS = 35
#: a parameter's doc says what it does and its unit, in a line or two of ``python -m bench methods``
MAX_DOC_CHARS = 160
#: ``ShapeGradientFlow.step``: the paper's four steps calling named additions, in at most this many lines
MAX_STEP_LINES = 40
#: the most instance attributes (``self.X = ...`` anywhere in the class) the flow may hold
MAX_FLOW_ATTRIBUTES = 25


def test_the_method_has_at_most_35_parameters():
    assert len(ShapeGradient.params) <= MAX_PARAMETERS, sorted(ShapeGradient.params)


def test_each_parameter_doc_is_a_line_or_two():
    long = {k: len(p.doc) for k, p in ShapeGradient.params.items() if len(p.doc) > MAX_DOC_CHARS}
    assert not long, long


def test_the_start_choice_settings_are_not_parameters():
    from methods.shape_gradient.choose import USUAL_START

    assert not set(USUAL_START) & set(ShapeGradient.params)


def test_flow_step_reads_as_the_four_steps_in_at_most_40_lines():
    lines = inspect.getsource(ShapeGradientFlow.step).splitlines()
    assert len(lines) <= MAX_STEP_LINES, len(lines)
    body = "\n".join(lines)
    for call in ("self._interpolate(", "self._gradient(", "self._precondition(", "self._step("):
        assert call in body, call


def _instance_attributes(cls) -> set[str]:
    """The names assigned as ``self.X`` (plain, annotated or augmented assignments) in the class's source."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    names = set()
    for node in ast.walk(tree):
        targets = (node.targets if isinstance(node, ast.Assign) else
                   [node.target] if isinstance(node, (ast.AnnAssign, ast.AugAssign)) else [])
        for target in targets:
            for part in ast.walk(target):
                if isinstance(part, ast.Attribute) and isinstance(part.value, ast.Name) and part.value.id == "self":
                    names.add(part.attr)
    return names


def test_the_flow_holds_at_most_25_attributes():
    names = _instance_attributes(ShapeGradientFlow)
    assert "stats" in names and len(names) <= MAX_FLOW_ATTRIBUTES, sorted(names)
