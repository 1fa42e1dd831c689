"""Topology against the data: the digital topology of the input's inside set next to the mesh's (docs/METRICS.md).

Truth-free, so for every row — phantoms and user scans alike.  The inside set is what the method was given:
``raw > level`` for a mask or an intensity image, φ < 0 for a level set (:attr:`phantoms.Volume.inside_raw`).

**The data.**  Its parts (inside components), cavities (background components that do not reach the grid's
border; the grid is padded with outside, as the mask methods pad it) and Euler characteristic χ, whence its
handles b1 = b0 + b2 − χ (for a solid in space, b1 is the summed genus of its boundary surfaces).  Digital
topology needs a *pair* of connectivities, one for the inside and the complementary one for the outside, so that
the inside and its complement do not cross each other: (6, 26) or (26, 6).  Neither alone is how a mesher
behaves: where two inside voxels touch only along a voxel edge, scikit-image's marching cubes keeps them apart
and VTK's flying edges and surface nets join them; where they touch only at a corner those three keep them
apart, while a smooth method (Poisson, the shape gradient) may bridge them.  Such a contact is a sub-voxel
feature: the grid cannot say whether the object touches there.  So both pairs are computed and a mesh is
compared with the range they span — (6, 26), the reading with the most parts and the fewest cavities, and
(26, 6), with the fewest parts and the most cavities; a count inside the range is consistent with the data.
Two parts touching at a voxel edge or corner are thus one part or two, as the mesh has it; two parts a voxel
apart are two.  The reported columns ``data_parts`` / ``data_cavities`` / ``data_handles`` are the (6, 26)
reading.

**Noise.**  On a noisy φ, φ < 0 holds speckles (one- or few-voxel parts and cavities) that a correct, smooth
mesh rightly leaves out.  Parts and cavities smaller than :data:`MIN_VOXELS` voxels are therefore not required
of a mesh — but they are allowed (a mesh part of the data's smallest is no extra part): a mesh is short of
parts only when it has fewer parts than the data has of at least :data:`MIN_VOXELS` voxels, and it has extra
ones only when its parts enclosing at least that volume outnumber all the data's parts.  The same hysteresis
applies to cavities.  Handles cannot be sorted by size, and the sign flips that make speckles also open and
close small tunnels through the noisy boundary layer; so a handle difference is tolerated up to the data's
number of speckles (parts and cavities under :data:`MIN_VOXELS`, the larger count of the two pairs).  A clean
mask or level set has no speckles and its handles are compared exactly (up to the pair).  At very low SNR
(noise σ above about h) the data's own topology is noise, and the flag says so.

**The mesh.**  Its shells are the faces joined through edges shared by exactly two faces (two surfaces touching
at a vertex stay apart); a closed shell wound outward (positive enclosed volume) bounds a part, one wound inward a
void (the suite's meshes are wound outward, so a cavity's shell faces into the cavity — and the winding number
the fidelity metrics read agrees).  ``mesh_genus`` is the summed genus of its closed shells, its handles.

**The comparison** names each kind of difference (:data:`KINDS`): ``dropped parts`` (a data part of at least
:data:`MIN_VOXELS` voxels with no mesh vertex in a grid cell touching it and less than half of it inside the
mesh), ``merged parts`` (fewer mesh parts than the data's, beyond the dropped ones and the range of the
pairs), ``extra parts``, ``filled cavities`` (fewer voids than the data's cavities), ``extra cavities``,
``closed handles`` (fewer handles than the data's: a tunnel filled, or a ring cut open) and ``opened handles``
(more: a hole through a wall, or a gap bridged into a ring).  Handles are compared only for a closed mesh (an
open one has no genus).

Cost: labelling and counting on the inside set's bounding box, all vectorised (scipy.ndimage.label, shifted
boolean views for χ); the mesh's part costs a few bincounts.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from geometry.mesh import face_signed_volumes, scored_mesh
from geometry.topology import component_euler

__all__ = ["MIN_VOXELS", "KINDS", "DATA_TOPOLOGY_NAMES", "digital_topology", "euler_characteristic", "mesh_shells",
           "data_topology_metrics", "compare"]

#: parts and cavities of the data smaller than this many voxels are speckles: not required of a mesh (see the
#: module docstring).  A 2 × 2 × 2 block is the smallest part whose mesh encloses a grid point's cell
MIN_VOXELS = 8

#: the kinds of difference, in the order a detail lists them
KINDS = ("dropped parts", "merged parts", "extra parts", "filled cavities", "extra cavities", "closed handles",
         "opened handles")

#: the registered columns this module fills
DATA_TOPOLOGY_NAMES = ("data_parts", "data_cavities", "data_handles", "mesh_voids", "mesh_genus", "topology_diffs")

_STRUCTURE = {6: ndimage.generate_binary_structure(3, 1), 26: ndimage.generate_binary_structure(3, 3)}


def euler_characteristic(inside: np.ndarray, connectivity: int) -> int:
    """χ of a voxel set with 6- or 26-connectivity of the inside (the outside's is the other one).

    26: the union of the closed voxel cubes, χ = V − E + F − C counting the cube complex's vertices, edges,
    faces and cubes (a cell is in it when any voxel around it is inside).  6: the complex whose vertices are the
    voxels, its edges the face-adjacent pairs, its squares the 2 × 2 blocks and its cubes the 2 × 2 × 2 blocks
    all inside.  Both by shifted views of the padded set.
    """
    x = np.pad(np.asarray(inside, bool), 1)
    anyof = connectivity == 26
    comb = np.logical_or if anyof else np.logical_and
    total = 0
    # cells of dimension 0..3 of the grid dual to the voxels: 2^k voxels around each, k the number of free axes
    for k in range(4):                                        # blocks of 2^k voxels, spanning k axes
        for axes in _axis_sets(k):
            offsets = [tuple(1 if (d in axes and (bits >> axes.index(d)) & 1) else 0 for d in range(3))
                       for bits in range(1 << k)]
            n = [s - (1 if d in axes else 0) for d, s in enumerate(x.shape)]
            views = [x[o[0]:o[0] + n[0], o[1]:o[1] + n[1], o[2]:o[2] + n[2]] for o in offsets]
            acc = views[0]
            for v in views[1:]:
                acc = comb(acc, v)
            count = int(np.count_nonzero(acc))
            # 26: a block of 2^k voxels is a (3 − k)-cell of the cube complex; 6: a k-cell of the voxel complex
            dim = 3 - k if anyof else k
            total += count if dim % 2 == 0 else -count
    return total


def _axis_sets(k: int) -> list[tuple[int, ...]]:
    from itertools import combinations

    return list(combinations(range(3), k))


def _labels(mask: np.ndarray, connectivity: int) -> tuple[np.ndarray, np.ndarray]:
    """(labels, sizes with sizes[0] = 0) of the components of ``mask``."""
    lab, n = ndimage.label(mask, _STRUCTURE[connectivity])
    sizes = np.bincount(lab.reshape(-1), minlength=n + 1)
    sizes[0] = 0
    return lab, sizes


def digital_topology(inside: np.ndarray, min_voxels: int = MIN_VOXELS) -> dict:
    """The data's topology under both connectivity pairs (see the module docstring).

    Parameters
    ----------
    inside : (nx, ny, nz) bool array, the inside voxels.
    min_voxels : parts and cavities smaller than this are speckles.

    Returns
    -------
    dict
        ``pairs``: {(fg, bg): {"parts", "parts_big", "cavities", "cavities_big", "euler", "handles",
        "speckles"}} for (6, 26) and (26, 6); ``labels``: the 26-connected parts' labels on the full grid and
        ``sizes`` their voxel counts (index 0 unused), for matching the mesh's vertices to parts.
    """
    inside = np.asarray(inside, bool)
    full_labels = np.zeros(inside.shape, np.int32)
    if not inside.any():
        zero = {"parts": 0, "parts_big": 0, "cavities": 0, "cavities_big": 0, "euler": 0, "handles": 0,
                "speckles": 0}
        return {"pairs": {(6, 26): dict(zero), (26, 6): dict(zero)}, "labels": full_labels, "sizes": np.zeros(1, int)}
    nz = [np.flatnonzero(inside.any(axis=tuple(a for a in range(3) if a != d))) for d in range(3)]
    box = tuple(slice(int(i[0]), int(i[-1]) + 1) for i in nz)
    sub = inside[box]
    padded_out = np.pad(~sub, 1, constant_values=True)          # the outside reaches round the box
    pairs = {}
    labels26 = sizes26 = None
    for fg, bg in ((6, 26), (26, 6)):
        lab, sizes = _labels(sub, fg)
        if fg == 26:
            labels26, sizes26 = lab, sizes
        blab, bsizes = _labels(padded_out, bg)
        bsizes[blab[0, 0, 0]] = 0                              # the outer background is no cavity
        parts, cav = sizes[1:], bsizes[1:][bsizes[1:] > 0]
        chi = euler_characteristic(sub, fg)
        b0, b2 = len(parts), len(cav)
        pairs[(fg, bg)] = {
            "parts": b0, "parts_big": int((parts >= min_voxels).sum()),
            "cavities": b2, "cavities_big": int((cav >= min_voxels).sum()),
            "euler": chi, "handles": b0 + b2 - chi,
            "speckles": int((parts < min_voxels).sum() + (cav < min_voxels).sum()),
        }
    full_labels[box] = labels26
    return {"pairs": pairs, "labels": full_labels, "sizes": sizes26}


def mesh_shells(vertices, faces: np.ndarray | None = None) -> dict:
    """The mesh's shells (faces joined through edges in exactly two faces): per shell its signed enclosed volume,
    whether it is closed, its Euler characteristic; and the face → shell labels.

    Returns
    -------
    dict
        ``n``, ``labels`` (F,), ``volume`` (n,), ``closed`` (n,) bool, ``euler`` (n,) int, ``genus`` (n,) int (of
        closed shells; 0 for open ones).
    """
    m = scored_mesh(vertices, faces)
    n, fl = m.face_components
    F = m.faces
    if n == 0:
        return {"n": 0, "labels": fl, "volume": np.zeros(0), "closed": np.zeros(0, bool), "euler": np.zeros(0, int),
                "genus": np.zeros(0, int)}
    vol = np.bincount(fl, weights=face_signed_volumes(m.vertices, F), minlength=n)
    euler, open_edges = component_euler(F, len(m.vertices), fl, n, groups=m.edge_groups)
    closed = open_edges == 0
    genus = np.where(closed, (2 - euler) // 2, 0)
    return {"n": int(n), "labels": fl, "volume": vol, "closed": closed, "euler": euler.astype(int),
            "genus": genus.astype(int)}


def _claimed_parts(vertices: np.ndarray, labels: np.ndarray, volume) -> np.ndarray:
    """The data parts (26-connected labels) some mesh vertex touches: a label at one of the 8 grid points of the
    cell the vertex lies in (vertices outside the grid touch nothing)."""
    idx = volume.world_to_index(vertices)
    shape = np.asarray(labels.shape)
    ok = np.all((idx >= 0) & (idx <= shape - 1), axis=1)
    if not ok.any():
        return np.zeros(0, np.int64)
    i0 = np.minimum(np.floor(idx[ok]).astype(np.int64), shape - 2)
    i0 = np.maximum(i0, 0)
    found = []
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                found.append(labels[i0[:, 0] + dx, i0[:, 1] + dy, i0[:, 2] + dz])
    got = np.concatenate(found)
    return np.unique(got[got > 0]).astype(np.int64)


def _range(lo: int, hi: int) -> str:
    return f"{lo}" if lo == hi else f"{lo}–{hi}"


def compare(data: dict, shells: dict, claimed: np.ndarray, covered: np.ndarray | None, voxel_volume: float,
            min_voxels: int = MIN_VOXELS) -> list[str]:
    """The differences between the data's topology (:func:`digital_topology`) and the mesh's
    (:func:`mesh_shells`), one ``"<kind>: <counts>"`` text per kind of :data:`KINDS` found (none: consistent).

    ``claimed``: the 26-connected data parts a mesh vertex touches; ``covered``: per part label, the share of its
    voxels inside the mesh (None: not known, a part no vertex touches counts as dropped)."""
    p6, p26 = data["pairs"][(6, 26)], data["pairs"][(26, 6)]
    sizes = data["sizes"]
    big = np.flatnonzero(sizes >= min_voxels)
    untouched = np.setdiff1d(big, claimed)
    if covered is not None:
        untouched = untouched[covered[untouched] < 0.5]
    dropped = len(untouched)
    small_vol = min_voxels * voxel_volume
    vol = shells["volume"]
    parts_all, voids_all = int((vol > 0).sum()), int((vol < 0).sum())
    parts_big, voids_big = int((vol >= small_vol).sum()), int((vol <= -small_vol).sum())
    out = []
    need_lo = p26["parts_big"]                                    # the fewest parts the data needs (26-connected)
    allowed_hi = p6["parts"]                                      # the most it allows (6-connected, speckles too)
    parts_txt = f"{_range(p26['parts_big'], p6['parts_big'])} in data, {parts_all} in mesh"
    if dropped:
        out.append(f"dropped parts: {dropped} of {len(big)} in data")
    if parts_all + dropped < need_lo:
        out.append(f"merged parts: {parts_txt}")
    if parts_big > allowed_hi:
        out.append(f"extra parts: {_range(p26['parts'], p6['parts'])} in data, {parts_big} in mesh")
    cav_lo, cav_hi = p6["cavities_big"], p26["cavities"]          # bg 26 joins cavities to the outside most
    if voids_all < cav_lo:
        out.append(f"filled cavities: {_range(cav_lo, p26['cavities_big'])} in data, {voids_all} in mesh")
    if voids_big > cav_hi:
        out.append(f"extra cavities: {_range(p6['cavities'], cav_hi)} in data, {voids_big} in mesh")
    if len(shells["closed"]) and shells["closed"].all():
        g = int(shells["genus"].sum())
        g_lo, g_hi = sorted((p6["handles"], p26["handles"]))
        slack = max(p6["speckles"], p26["speckles"])
        tol = f" (± {slack} for the data's speckles)" if slack else ""
        if g < g_lo - slack:
            out.append(f"closed handles: {_range(g_lo, g_hi)} in data{tol}, {g} in mesh")
        elif g > g_hi + slack:
            out.append(f"opened handles: {_range(g_lo, g_hi)} in data{tol}, {g} in mesh")
    return out


def data_topology_metrics(V, F: np.ndarray | None, volume, mesh_inside: np.ndarray | None = None,
                          data: dict | None = None) -> tuple[dict, str]:
    """``(columns, detail)``: the :data:`DATA_TOPOLOGY_NAMES` columns of a mesh against the volume it was made
    from, and the ``; ``-joined differences (empty: none; see the module docstring).

    Parameters
    ----------
    V, F : the mesh (compacted), world coordinates: a :class:`geometry.mesh.ScoredMesh` and None, or the arrays.
    volume : phantoms.Volume — the volume the method was given (its :attr:`~phantoms.Volume.inside_raw`).
    mesh_inside : (nx, ny, nz) bool array, optional — which grid points the mesh encloses (its winding number,
        computed once for the fidelity metrics); without it a part no mesh vertex touches counts as dropped.
    data : dict, optional — :func:`digital_topology` of the volume's inside set, when computed already.
    """
    m = scored_mesh(V, F)
    if data is None:
        data = digital_topology(volume.inside_raw)
    shells = mesh_shells(m)
    labels, sizes = data["labels"], data["sizes"]
    claimed = _claimed_parts(m.vertices, labels, volume)
    covered = None
    if mesh_inside is not None and len(sizes) > 1:
        inside_count = np.bincount(labels[np.asarray(mesh_inside, bool)], minlength=len(sizes))
        covered = inside_count / np.maximum(sizes, 1)
    diffs = compare(data, shells, claimed, covered, float(np.prod(volume.spacing)))
    p6 = data["pairs"][(6, 26)]
    cols = {"data_parts": int(p6["parts_big"]), "data_cavities": int(p6["cavities_big"]),
            "data_handles": int(p6["handles"]), "mesh_voids": int((shells["volume"] < 0).sum()),
            "mesh_genus": int(shells["genus"].sum()), "topology_diffs": len(diffs)}
    return cols, "; ".join(diffs)


def nan_columns() -> dict:
    """The columns without a volume: NaN."""
    return {k: math.nan for k in DATA_TOPOLOGY_NAMES}
