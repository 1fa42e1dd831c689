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


@register_method
class WorkerKillerMethod(Method):
    name = "worker_killer"
    description = "SIGKILLs the Dask worker process that runs it (a cell that keeps killing its workers)"
    params = {"seconds": Param(0.0, "how long to sleep first", float, min=0.0)}

    def reconstruct(self, volume):
        import os
        import signal

        import psutil

        time.sleep(self.config["seconds"])
        # this cell's process <- the worker's fork server <- the Dask worker process
        os.kill(psutil.Process(os.getppid()).ppid(), signal.SIGKILL)
        time.sleep(60)  # the lifeline ends this process once its worker is gone
