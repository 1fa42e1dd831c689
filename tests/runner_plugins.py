"""Methods that misbehave on purpose, for the runner tests.

The runner's worker processes import this module by name (``--import runner_plugins`` with ``tests/`` on
PYTHONPATH), which registers the methods there too — the way a user's plug-in module would.
"""

from __future__ import annotations

import os
import signal
import time

from methods import Method, Param, register_method


@register_method
class FailingMethod(Method):
    name = "failing"
    description = "raises an exception on every volume (runner tests)"
    params: dict = {}

    def reconstruct(self, volume):
        raise RuntimeError("deliberate failure for the runner tests")


@register_method
class SleepyMethod(Method):
    name = "sleepy"
    description = "sleeps, then fails (runner timeout tests)"
    params = {"seconds": Param(60.0, "how long to sleep", float, min=0.0)}

    def reconstruct(self, volume):
        time.sleep(self.config["seconds"])
        raise RuntimeError("woke up")


@register_method
class CrashingMethod(Method):
    name = "crashing"
    description = "kills its own process (runner isolation tests)"
    params: dict = {}

    def reconstruct(self, volume):
        os.kill(os.getpid(), signal.SIGKILL)


@register_method
class InwardMethod(Method):
    name = "inward"
    description = "marching cubes with every face flipped: scores like the correct mesh, but faces inward"
    params: dict = {}

    def reconstruct(self, volume):
        from methods import Reconstruction, get_method

        rec = get_method("marching_cubes").reconstruct(volume)
        rec.mesh.faces = rec.mesh.faces[:, ::-1]
        return Reconstruction(rec.mesh, {})
