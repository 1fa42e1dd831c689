"""Anatomy-like phantoms with exact truth: the shapes medical segmentations hold and smooth solids do not —
a thin vault with foramina, a branching vessel tree, a solid with cavities, separate vertebra-like parts, a
porous lattice of high genus and two parts a fraction of a voxel apart.

Each is a boolean combination of finely tessellated primitives (spheres, capsules, cylinders, boxes) computed
by manifold3d, whose booleans are exact in topology and robust (no crossing, no gap: a closed, oriented,
embedded polyhedron); the phantom is that polyhedron as a :class:`~phantoms.mesh.MeshPhantom` (not normalised),
so the truth *is* the polyhedron: the certified exact distance, the winding-number inside test, area-uniform
surface samples, and exact volume, area, components and genus of the mesh.  A ``min`` of primitive distances
would have the right zero set but not the right distance inside; it is kept only as :meth:`ideal_sdf`, the
ideal (untessellated) shape's CSG bound, for the tests: its sign is exact and its magnitude a lower bound of the
distance, so wherever ``|ideal_sdf| > tessellation_error`` the mesh and the ideal shape agree on the side.

Sizes: the body fits the default box [−2.5, 2.5]³ as the smooth phantoms do (in fractions of ``extent``); the
thin features — thickness, gaps, radii, struts — are given **in voxels** of the grid with ``n`` points per axis
over [−extent, extent]³ (h = 2·extent / (n − 1)); ``seed`` draws the positions and directions.  The designed
number of components and genus are computed from the parameters (:attr:`expected_components`,
:attr:`expected_genus`) and checked against the built mesh: parameters that would merge or cut parts are refused.
Where the ideal shape has a closed-form volume and area (:meth:`ideal_volume`, :meth:`ideal_area`), the mesh's
differ from them by the tessellation error only.

A phantom with non-default parameters is named ``NAME?key=value&...`` (``vault_shell?thickness=0.75&seed=2``),
see :func:`parse_anatomy_spec`.
"""

from __future__ import annotations

from geometry.errors import InputError

from .base import ANATOMY_N, INT_PARAMS, AnatomyPhantom
from .parts import Lattice, SpineParts, VesselTree
from .shells import CavitySolid, TouchingPair, VaultShell

__all__ = ["ANATOMY", "AnatomyPhantom", "VaultShell", "VesselTree", "CavitySolid", "SpineParts", "Lattice",
           "TouchingPair", "parse_anatomy_spec", "ANATOMY_N"]


#: the anatomy phantoms by name
ANATOMY: dict[str, type[AnatomyPhantom]] = {
    cls.name: cls for cls in (VaultShell, VesselTree, CavitySolid, SpineParts, Lattice, TouchingPair)
}


def parse_anatomy_spec(spec: str) -> tuple[str, dict]:
    """``'vault_shell?thickness=0.75&seed=2'`` → ``('vault_shell', {'thickness': 0.75, 'seed': 2})``.

    Raises
    ------
    InputError
        Not an anatomy phantom, an option it does not take, or a value that is not a number.
    """
    name, _, query = str(spec).partition("?")
    if name not in ANATOMY:
        raise InputError(f"{spec!r}: {name!r} is not an anatomy phantom ({', '.join(ANATOMY)})")
    valid = ANATOMY[name].parameter_names
    params: dict = {}
    for item in filter(None, query.split("&")):
        key, eq, value = item.partition("=")
        if key not in valid or not eq:
            raise InputError(f"phantom {spec!r}: unknown option {item!r}; valid: {', '.join(valid)} (key=value)")
        try:
            num = float(value)
        except ValueError:
            raise InputError(f"phantom {spec!r}: {key} must be a number, got {value!r}") from None
        params[key] = int(num) if num.is_integer() and key in INT_PARAMS else num
    return name, params
