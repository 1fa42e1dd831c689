"""Methods using the optional hooks of :class:`methods.Method`, for the tests of ``skip_reason`` and ``warm_up``.

Imported by name (``--import hook_plugins`` with ``tests/`` on PYTHONPATH), as a user's plug-in module would be.
"""

from __future__ import annotations

import time

import numpy as np

from methods import Method, Param, ReconstructionFailed, get_method, register_method

#: seconds each process's first warm_up of ``warm_mc`` sleeps (a stand-in for compiling kernels)
WARM_SECONDS = 0.4
_WARMED: list[bool] = []


@register_method
class PickyMC(Method):
    name = "picky_mc"
    description = "marching cubes that declines grids of fewer than min_n points per axis (hook tests)"
    params = {"min_n": Param(30, "fewest grid points per axis it takes", min=0)}

    def skip_reason(self, volume):
        n = max(volume.shape)
        if n < self.config["min_n"]:
            return f"the grid has {n} points per axis,\n fewer than the {self.config['min_n']} it needs"
        return None

    def reconstruct(self, volume):
        return get_method("marching_cubes").reconstruct(volume)


@register_method
class WarmMC(Method):
    name = "warm_mc"
    description = "marching cubes whose first warm_up in a process takes WARM_SECONDS (hook tests)"
    params: dict = {}

    def warm_up(self):
        if not _WARMED:
            time.sleep(WARM_SECONDS)
            _WARMED.append(True)

    def reconstruct(self, volume):
        if not _WARMED:
            raise ReconstructionFailed("reconstruct ran before warm_up")
        return get_method("marching_cubes").reconstruct(volume)


@register_method
class BadHooks(Method):
    name = "bad_hooks"
    description = "hooks that break their contract (hook tests)"
    params = {"hook": Param("skip_type", "which hook breaks", choices=("skip_type", "skip_raises", "warm_raises"))}

    def skip_reason(self, volume):
        if self.config["hook"] == "skip_raises":
            raise ValueError("no idea")
        return 3 if self.config["hook"] == "skip_type" else None

    def warm_up(self):
        raise RuntimeError("the kernels do not compile")

    def reconstruct(self, volume):  # pragma: no cover - never reached
        return get_method("marching_cubes").reconstruct(volume)


@register_method
class DegenerateMesh(Method):
    name = "degenerate_mesh"
    description = "a closed tetrahedron collapsed to one point of the zero set (zero area), or a mesh without faces"
    params = {"kind": Param("collapsed", "what the mesh is", choices=("collapsed", "no_faces"))}

    def reconstruct(self, volume):
        import trimesh

        from methods import Reconstruction

        v = np.tile(get_method("marching_cubes").reconstruct(volume).mesh.vertices[:1], (4, 1))
        f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        if self.config["kind"] == "no_faces":
            f = f[:0]
        return Reconstruction(trimesh.Trimesh(v, f, process=False), {})


@register_method
class SlowImportMC(Method):
    name = "slow_import_mc"
    description = "marching cubes that imports a slow library lazily, as the VTK methods do (hook tests)"
    params: dict = {}
    imports = ("slow_import_library",)

    def reconstruct(self, volume):
        import slow_import_library  # noqa: F401

        return get_method("marching_cubes").reconstruct(volume)


@register_method
class SleepyMC(Method):
    name = "sleepy_mc"
    description = "marching cubes after a pause of `seconds` (a long method, for progress tests)"
    params = {"seconds": Param(1.0, "seconds it sleeps first", min=0.0)}

    def reconstruct(self, volume):
        time.sleep(self.config["seconds"])
        return get_method("marching_cubes").reconstruct(volume)
