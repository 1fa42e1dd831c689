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


#: each class of invalid output the suite must catch, and how ``broken`` makes it from a correct mesh
BROKEN_KINDS = ("nonfinite", "empty", "open", "inward", "mixed", "index", "outside", "nonmanifold")


@register_method
class BrokenMethod(Method):
    name = "broken_output"
    description = "marching cubes, then broken on purpose in one way (validity tests): " + ", ".join(BROKEN_KINDS)
    params = {"kind": Param("open", "how to break the mesh", str, choices=BROKEN_KINDS)}

    def reconstruct(self, volume):
        import numpy as np
        import trimesh

        from methods import Reconstruction, get_method

        m = get_method("marching_cubes").reconstruct(volume).mesh
        v, f = np.asarray(m.vertices, float).copy(), np.asarray(m.faces).copy()
        kind = self.config["kind"]
        if kind == "nonfinite":
            v[0] = np.nan
        elif kind == "empty":
            v, f = np.zeros((0, 3)), np.zeros((0, 3), int)
        elif kind == "open":
            f = f[10:]
        elif kind == "inward":
            f = f[:, ::-1]
        elif kind == "mixed":
            f[: len(f) // 2] = f[: len(f) // 2, ::-1]
        elif kind == "index":
            v = volume.world_to_index(v)
        elif kind == "outside":
            v = v + 10.0 * (volume.upper - volume.lower)
        elif kind == "nonmanifold":                      # a fin: a third face on one edge
            v = np.vstack([v, v[f[0, 0]] + 3 * volume.h])
            f = np.vstack([f, [[f[0, 0], f[0, 1], len(v) - 1]]])
        return Reconstruction(trimesh.Trimesh(v, f, process=False), {})


@register_method
class ExitingMethod(Method):
    name = "exiting"
    description = "calls sys.exit(0) instead of returning (plug-in contract tests)"
    params: dict = {}

    def reconstruct(self, volume):
        import sys

        sys.exit(0)


@register_method
class BadInfoMethod(Method):
    name = "bad_info"
    description = "marching cubes whose info has one value of the wrong type (plug-in contract tests)"
    params = {"key": Param("warnings", "which info key is wrong", str,
                           choices=("warnings", "iterations", "stop_reason", "energy_final"))}

    def reconstruct(self, volume):
        from methods import Reconstruction, get_method

        wrong = {"warnings": "a string", "iterations": "many", "stop_reason": 3, "energy_final": "low"}
        rec = get_method("marching_cubes").reconstruct(volume)
        key = self.config["key"]
        return Reconstruction(rec.mesh, {key: wrong[key]})


@register_method
class HugeMessageMethod(Method):
    name = "huge_message"
    description = "raises an exception whose message has 5 million characters (message capping tests)"
    params: dict = {}

    def reconstruct(self, volume):
        raise RuntimeError("x" * 5_000_000)
