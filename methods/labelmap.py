"""What the mask-native methods share: the label map a volume holds, and the repairs of a surface extracted from it.

A volume of kind ``mask`` or ``intensity`` carries its image (``raw``, inside where raw > ``level``); a signed
distance is read as the mask φ < 0 (:attr:`phantoms.Volume.inside_raw`).  :func:`padded_labels` pads that mask
with one outside voxel on every face (3D Slicer does so when the mask touches the border; a padded face changes
nothing elsewhere).  The label map goes to VTK through :func:`methods.isosurface.vtk_image`;
:func:`close_seams` and :func:`fill_edge_contacts` close what VTK's SurfaceNets leaves open on a speckled mask.
"""

from __future__ import annotations

import numpy as np
import trimesh

from phantoms import InputError, Volume

__all__ = ["padded_labels", "close_seams", "fill_edge_contacts"]


def padded_labels(volume: Volume, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(uint8 label map, 1 inside, padded by one outside voxel; world origin of its voxel (0, 0, 0))."""
    inside = volume.inside_raw
    if not inside.any() or inside.all():
        raise InputError(f"method {name!r}: the mask has no {'inside' if not inside.any() else 'outside'} voxels")
    labels = np.pad(inside.astype(np.uint8), 1)
    return labels, volume.origin - volume.spacing


def close_seams(faces: np.ndarray) -> tuple[np.ndarray, int]:
    """(faces with every boundary loop fan-triangulated, number of loops closed).

    VTK's SurfaceNets gives a vertex two copies where inside voxels touch only along an edge next to other
    inside voxels (a speckled mask), and pairs the copies inconsistently: the four faces around that edge
    leave a loop of four boundary edges between the copies (a zero-area slit before smoothing, a small hole
    after).  Each loop — the shortest cycle of boundary half-edges through an edge, taken one at a time — is
    closed by a fan traversing its edges the other way (so the patch keeps the faces' orientation) from the
    loop vertex whose diagonals are no edge yet (so every edge ends in two faces).  Open chains are left.
    """
    faces = np.asarray(faces, np.int64)
    half = trimesh.geometry.faces_to_edges(faces)                  # the 3F directed edges
    k = int(faces.max()) + 1
    boundary = half[~np.isin(half[:, 0] * k + half[:, 1], half[:, 1] * k + half[:, 0])]
    if len(boundary) == 0:
        return faces, 0
    out: dict[int, set[int]] = {}
    for a, b in boundary.tolist():
        out.setdefault(a, set()).add(b)
    edges = set(map(tuple, np.sort(half, axis=1).tolist()))
    patches, loops = [], 0
    for a, b in boundary.tolist():
        if b not in out.get(a, ()):
            continue
        loop = _shortest_loop(out, a, b)
        if loop is None:
            continue
        for u, w in zip(loop, loop[1:] + loop[:1]):
            out[u].discard(w)
        fan = _fan(loop, edges)
        edges.update((min(u, w), max(u, w)) for t in fan for u, w in ((t[0], t[1]), (t[1], t[2]), (t[0], t[2])))
        patches += fan
        loops += 1
    return np.concatenate([faces, np.asarray(patches, np.int64).reshape(-1, 3)]), loops


def _shortest_loop(out: dict, a: int, b: int, longest: int = 64):
    """The shortest cycle a → b → … → a of the half-edges ``out`` (breadth first), or None."""
    parent, frontier = {b: a}, [b]
    while frontier and len(parent) < longest * 4:
        nxt = []
        for v in frontier:
            for w in out.get(v, ()):
                if w == a:
                    loop = [v]
                    while loop[-1] != b:
                        loop.append(parent[loop[-1]])
                    return [a] + loop[::-1]
                if w not in parent:
                    parent[w] = v
                    nxt.append(w)
        frontier = nxt
    return None


def _fan(loop: list[int], edges: set) -> list[tuple[int, int, int]]:
    """Triangles closing ``loop`` (boundary half-edges in its order) the other way round, from the first
    rotation whose fan diagonals are not edges yet."""
    n = len(loop)
    for r in range(n):
        lp = loop[r:] + loop[:r]
        if not any((min(lp[0], w), max(lp[0], w)) in edges for w in lp[2:-1]):
            break
    return [(lp[0], lp[j + 1], lp[j]) for j in range(1, n - 1)]


def fill_edge_contacts(labels: np.ndarray, most: int = 100) -> tuple[np.ndarray, int]:
    """(``labels`` with no two inside voxels touching only along an edge, number of voxels added).

    Where a 2 × 2 square of voxels in any axis plane holds inside voxels on one diagonal only, one voxel of
    the other diagonal is set inside (the result is a closed, edge-manifold SurfaceNets mesh whatever the
    mask); repeated until none is left (each pass may make new ones).  The added voxels lie between inside
    voxels, so a padded border stays outside.
    """
    m = labels.astype(bool)
    added = 0
    for _ in range(most):
        change = np.zeros_like(m)
        for ax, bx in ((0, 1), (0, 2), (1, 2)):
            def part(i, j):
                return tuple(slice(i, m.shape[d] - 1 + i) if d == ax else slice(j, m.shape[d] - 1 + j)
                             if d == bx else slice(None) for d in range(3))
            a, b, c, d = m[part(0, 0)], m[part(1, 1)], m[part(1, 0)], m[part(0, 1)]
            change[part(1, 0)] |= a & b & ~c & ~d
            change[part(0, 0)] |= c & d & ~a & ~b
        change &= ~m
        if not change.any():
            break
        m |= change
        added += int(change.sum())
    return m.astype(labels.dtype), added
