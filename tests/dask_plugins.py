"""A slow-but-correct test method for the Dask executor tests (``--import dask_plugins``).

``napping`` sleeps, then reconstructs with marching cubes: long enough for a test to kill the worker that runs
it mid-cell, and a real result so every row of the run can be checked.  ``tag`` only tells cells apart.
"""

from __future__ import annotations

import time

from methods import Method, Param, get_method, register_method


@register_method
class NappingMethod(Method):
    name = "napping"
    description = "sleeps, then marching cubes (Dask executor tests)"
    params = {"seconds": Param(1.0, "how long to sleep first", float, min=0.0),
              "tag": Param(0, "distinguishes otherwise identical cells", int, min=0)}

    def reconstruct(self, volume):
        time.sleep(self.config["seconds"])
        return get_method("marching_cubes").reconstruct(volume)
