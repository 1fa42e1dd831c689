"""Methods that break the method contract on purpose, one way each, for ``check-method`` tests.

Imported by name (``--import broken_methods`` with ``tests/`` on the path), as a user's module would be.  Each
is marching cubes with one thing wrong, so the check must find exactly that.
"""

from __future__ import annotations

import time

import numpy as np
import trimesh

from methods import Method, Param, Reconstruction, check_volume, get_method, register_method


def _mc(volume) -> trimesh.Trimesh:
    return get_method("marching_cubes").reconstruct(volume).mesh


@register_method
class BrokenOpen(Method):
    name = "broken_open"
    description = "marching cubes with a tenth of the faces dropped: open"

    def reconstruct(self, volume):
        mesh = _mc(volume)
        keep = np.arange(len(mesh.faces)) % 10 != 0
        return Reconstruction(trimesh.Trimesh(mesh.vertices, mesh.faces[keep], process=False), {})


@register_method
class BrokenInward(Method):
    name = "broken_inward"
    description = "marching cubes with every face reversed: inward"

    def reconstruct(self, volume):
        mesh = _mc(volume)
        return Reconstruction(trimesh.Trimesh(mesh.vertices, mesh.faces[:, ::-1], process=False), {})


@register_method
class BrokenIndex(Method):
    name = "broken_index"
    description = "marching cubes left in voxel-index coordinates"

    def reconstruct(self, volume):
        mesh = _mc(volume)
        ijk = volume.world_to_index(mesh.vertices)
        return Reconstruction(trimesh.Trimesh(ijk, mesh.faces, process=False), {"iterations": 0})


@register_method
class BrokenNaN(Method):
    name = "broken_nan"
    description = "marching cubes with one vertex NaN"

    def reconstruct(self, volume):
        mesh = _mc(volume)
        v = np.array(mesh.vertices)
        v[0] = np.nan
        return Reconstruction(trimesh.Trimesh(v, mesh.faces, process=False), {})


@register_method
class BrokenType(Method):
    name = "broken_type"
    description = "returns a bare trimesh instead of a methods.Reconstruction"

    def reconstruct(self, volume):
        return _mc(volume)


@register_method
class BrokenRaises(Method):
    name = "broken_raises"
    description = "raises a ValueError (not InputError / ReconstructionFailed) on every volume"

    def reconstruct(self, volume):
        raise ValueError("deliberate bug for the check-method tests")


@register_method
class BrokenNoCheck(Method):
    name = "broken_no_check"
    description = "valid meshes, but returns a surface for a volume with no zero crossing"

    def reconstruct(self, volume):
        if volume.has_zero_crossing():
            check_volume(volume, self.name)
            return Reconstruction(_mc(volume), {})
        return Reconstruction(trimesh.creation.icosphere(1, 0.5), {})


class _SlowFaces(trimesh.Trimesh):
    """A mesh whose faces take ``slow_s`` seconds to read once the method has returned it."""

    slow_s = 0.0

    @property
    def faces(self):
        if self.slow_s:
            time.sleep(self.slow_s)
        return trimesh.Trimesh.faces.fget(self)

    @faces.setter
    def faces(self, values):
        trimesh.Trimesh.faces.fset(self, values)


@register_method
class SlowToScore(Method):
    name = "slow_to_score"
    description = "marching cubes in milliseconds, but its mesh takes `seconds` to score (time-limit tests)"
    params = {"seconds": Param(60.0, "seconds each read of the faces takes once returned", float, min=0.0)}

    def reconstruct(self, volume):
        mc = _mc(volume)
        mesh = _SlowFaces(mc.vertices, mc.faces, process=False)
        mesh.slow_s = self.config["seconds"]
        return Reconstruction(mesh, {"iterations": 0})



@register_method
class BrokenHangs(Method):
    name = "broken_hangs"
    description = "never returns (a loop without a stopping rule)"

    def reconstruct(self, volume):
        time.sleep(3600)


@register_method
class BrokenAborts(Method):
    name = "broken_aborts"
    description = "calls os.abort() (compiled code that crashes)"

    def reconstruct(self, volume):
        import os

        os.abort()
