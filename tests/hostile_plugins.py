"""Methods that attack the runner's resources on purpose, for the memory-limit and isolation tests.

Imported by name (``--import hostile_plugins`` with ``tests/`` on PYTHONPATH), as a user's plug-in module
would be.  Each misbehaves in one way; the others of the grid must not notice.
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import trimesh

from methods import Method, Param, Reconstruction, get_method, register_method

#: what the hungry methods ask for: far more than any test limit (and than the test machines have)
HUGE = 30 * 2 ** 30 // 8

#: the pid of the process that forked this one (the fork server), taken at the fork itself: a cell that
#: looked only when its method starts could miss a server killed before that
_FORKED_BY = [os.getppid()]
os.register_at_fork(after_in_child=lambda: _FORKED_BY.__setitem__(0, os.getppid()))


def _mc(volume) -> trimesh.Trimesh:
    return get_method("marching_cubes").reconstruct(volume).mesh


@register_method
class MemoryHog(Method):
    name = "memory_hog"
    description = "allocates 30 GB (np.ones) before marching cubes: over any memory limit, in the method"
    params: dict = {}

    def reconstruct(self, volume):
        big = np.ones((HUGE,))
        return Reconstruction(_mc(volume), {"size": big.size})


class _HungryFaces(trimesh.Trimesh):
    """A mesh whose faces cost 30 GB to read once the method has returned it (scoring runs out of memory)."""

    returned = False

    @property
    def faces(self):
        if self.returned:
            np.ones((HUGE,))
        return trimesh.Trimesh.faces.fget(self)

    @faces.setter
    def faces(self, values):
        trimesh.Trimesh.faces.fset(self, values)


@register_method
class HungryToScore(Method):
    name = "hungry_to_score"
    description = "marching cubes, but its mesh needs 30 GB to score: over any memory limit, in scoring"
    params: dict = {}

    def reconstruct(self, volume):
        mc = _mc(volume)
        mesh = _HungryFaces(mc.vertices, mc.faces, process=False)
        mesh.returned = True
        return Reconstruction(mesh, {})


@register_method
class KillsParent(Method):
    name = "kills_parent"
    description = "SIGKILLs its parent process (the local executor's fork server), then fails"
    params: dict = {}
    relative_cost = 50.0             # started right after slow_ok, so that one runs while the server dies

    def reconstruct(self, volume):
        os.kill(os.getppid(), signal.SIGKILL)
        raise RuntimeError("killed my parent")


@register_method
class KillsGroup(Method):
    name = "kills_group"
    description = "SIGKILLs its whole process group (os.killpg(0, SIGKILL))"
    params: dict = {}

    def reconstruct(self, volume):
        os.killpg(0, signal.SIGKILL)
        raise RuntimeError("still alive after killing my process group")


@register_method
class SlowOk(Method):
    name = "slow_ok"
    description = ("marching cubes after waiting up to `seconds` for its fork server to die: a well-behaved "
                   "cell that runs beside the hostile ones")
    params = {"seconds": Param(3.0, "longest wait for the fork server to die", float, min=0.0)}
    relative_cost = 100.0            # started first: it runs while the others attack

    def reconstruct(self, volume):
        # waits for the orphaning rather than for a fixed time, so a loaded machine that starts the killer
        # late cannot make the test pass or fail by chance; the test checks the orphan case really happened
        end = time.monotonic() + self.config["seconds"]
        while os.getppid() == _FORKED_BY[0] and time.monotonic() < end:
            time.sleep(0.05)
        return Reconstruction(_mc(volume), {"reparented": os.getppid() != _FORKED_BY[0]})
