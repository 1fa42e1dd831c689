"""Methods with and without a cost model, for the estimate tests (``--import cost_plugins`` with ``tests/`` on
PYTHONPATH registers them in the worker processes too)."""

from __future__ import annotations

from methods import Method, Param, register_method
from methods.marching_cubes import MarchingCubes


@register_method
class CostlyMethod(MarchingCubes):
    """Marching cubes (fast) that claims to need ``estimate`` seconds: refused under a shorter limit unless
    forced, and then ``ok`` — so a forced cell is seen to have run."""

    name = "costly"
    description = "marching cubes with a cost model claiming `estimate` seconds (estimate tests)"
    params = {**MarchingCubes.params, "estimate": Param(3600.0, "the claimed run time, s", float, min=0.0)}

    def estimate_seconds(self, shape, n_crossing_cells=None):
        return self.config["estimate"]


@register_method
class UncostedMethod(MarchingCubes):
    """Marching cubes under another name, with no cost model (the base class's None)."""

    name = "uncosted"
    description = "marching cubes without a cost model (estimate tests)"


@register_method
class BrokenModelMethod(MarchingCubes):
    """A cost model that raises: the cell must run, not be refused or stop the run."""

    name = "broken_model"
    description = "marching cubes whose cost model raises (estimate tests)"

    def estimate_seconds(self, shape, n_crossing_cells=None):
        raise ZeroDivisionError("deliberately broken cost model")


__all__ = ["CostlyMethod", "UncostedMethod", "BrokenModelMethod", "Method"]
