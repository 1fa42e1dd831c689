"""Pieces of a sampled region φ < level and the lowest saddles of φ between them: which pieces a thin layer of
small φ joins, and the voxel paths through those saddles.

Why: where an object has a part thinner than a voxel (a leg, a wing, a neck between two lobes), the samples of φ
inside it may all be positive, so the region φ < 0 falls apart at grid resolution into pieces the object joins.
Between two such pieces φ stays small along the thin part; between two separate objects it rises to half their
distance.  The *saddle* of two pieces is the lowest value a voxel path from one to the other must climb to
(the minimax of φ along 26-connected paths).  Joining the pieces along a spanning tree of lowest saddles —
built by a watershed of φ from the pieces (scikit-image, flooding by increasing φ) and a minimum spanning tree of
the basins' lowest boundary values (the two are the same tree: Cousty et al., watershed cuts) — gives the
solid the object most plausibly has.

* :func:`piece_saddles` — the pieces, their sizes, and the spanning tree of saddles below ``join_below``.
* :func:`join_pieces` — a copy of φ where the samples of every tree path are set at most ``-depth``, so a genus-0 growth
  (:func:`methods.shape_gradient.digital.homotopic_growth`) from the largest piece runs through each path into the next
  piece.  A path is 6-connected (a diagonal step is split into axis steps through the lower sample), so that marching
  cubes of the result has an unambiguous tube along it.
"""

from __future__ import annotations

from collections import deque

import numpy as np
from scipy import ndimage

__all__ = ["piece_saddles", "join_pieces"]

_FORWARD = [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) > (0, 0, 0)]
_ALL26 = [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)]


def _shifted(a: np.ndarray, off) -> tuple[np.ndarray, np.ndarray]:
    """(a[p], a[p + off]) over every p where both are in the array."""
    lo = tuple(slice(max(0, -o), n - max(0, o)) for n, o in zip(a.shape, off))
    hi = tuple(slice(max(0, o), n - max(0, -o)) for n, o in zip(a.shape, off))
    return a[lo], a[hi]


def _boundary_edges(basins: np.ndarray, phi: np.ndarray):
    """Lowest boundary value between every two adjacent basins: {(a, b): (value, index p, index q)} with p in
    basin a, q in basin b (a < b), value = max(φ_p, φ_q), minimal over 26-adjacent pairs."""
    flat = np.arange(phi.size).reshape(phi.shape)
    best: dict = {}
    for off in _FORWARD:
        la, lb = _shifted(basins, off)
        pick = (la > 0) & (lb > 0) & (la != lb)
        if not pick.any():
            continue
        fa, fb = _shifted(flat, off)
        pa, pb = fa[pick], fb[pick]
        a, b = la[pick], lb[pick]
        w = np.maximum(phi.ravel()[pa], phi.ravel()[pb])
        swap = a > b
        a, b = np.where(swap, b, a), np.where(swap, a, b)
        pa, pb = np.where(swap, pb, pa), np.where(swap, pa, pb)
        order = np.lexsort((w, b, a))
        a, b, w, pa, pb = a[order], b[order], w[order], pa[order], pb[order]
        first = np.ones(len(a), bool)
        first[1:] = (a[1:] != a[:-1]) | (b[1:] != b[:-1])
        for ai, bi, wi, p, q in zip(a[first], b[first], w[first], pa[first], pb[first]):
            key = (int(ai), int(bi))
            if key not in best or wi < best[key][0]:
                best[key] = (float(wi), int(p), int(q))
    return best


def piece_saddles(phi: np.ndarray, level: float, join_below: float) -> dict:
    """The 26-connected pieces of ``phi < level`` and the spanning forest of their lowest saddles below
    ``join_below`` (``join_below`` ≤ ``level``: no joins).

    Returns ``{"labels": int array (0 = not in a piece), "sizes": samples per piece (index = label − 1),
    "basins": the watershed of φ from the pieces inside φ < join_below, "edges": [(saddle, a, b, p, q)]}`` —
    the forest's edges in increasing saddle order, pieces a and b joined through the adjacent samples p (basin a)
    and q (basin b), flat indices into ``phi``.
    """
    from skimage.segmentation import watershed

    labels, n = ndimage.label(phi < level, structure=np.ones((3, 3, 3), bool))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    out = {"labels": labels, "sizes": sizes, "basins": labels, "edges": []}
    if n < 2 or join_below <= level:
        return out
    basins = watershed(phi, markers=labels, mask=phi < join_below, connectivity=3)
    out["basins"] = basins
    parent = list(range(n + 1))

    def root(c):
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c
    cand = sorted((w, a, b, p, q) for (a, b), (w, p, q) in _boundary_edges(basins, phi).items())
    for w, a, b, p, q in cand:
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[ra] = rb
            out["edges"].append((w, a, b, p, q))
    return out


def _descend(start: int, basin: int, piece_labels: np.ndarray, basins: np.ndarray, phi: np.ndarray,
             top: float) -> list[int]:
    """Shortest 26-connected path (flat indices, from ``start``) inside ``basin`` through samples with φ ≤
    ``top`` to the first sample of the basin's piece; [start] if it is one already."""
    shape = phi.shape
    if piece_labels.flat[start] == basin:
        return [start]
    prev = {start: -1}
    queue = deque([start])
    while queue:
        c = queue.popleft()
        ci = np.unravel_index(c, shape)
        for off in _ALL26:
            q = tuple(ci[d] + off[d] for d in range(3))
            if min(q) < 0 or any(q[d] >= shape[d] for d in range(3)):
                continue
            f = int(np.ravel_multi_index(q, shape))
            if f in prev or basins.flat[f] != basin or phi.flat[f] > top:
                continue
            prev[f] = c
            if piece_labels.flat[f] == basin:
                path = [f]
                while prev[path[-1]] != -1:
                    path.append(prev[path[-1]])
                return path[::-1]
            queue.append(f)
    return [start]          # not reached (the basin is flooded from its piece, so this does not happen)


def _six_connected(path: list[tuple[int, ...]], phi: np.ndarray) -> list[tuple[int, ...]]:
    """The samples of a 26-connected path with every diagonal step split into axis steps, each through the
    lower of the samples it could pass."""
    out = [path[0]]
    for q in path[1:]:
        p = list(out[-1])
        while tuple(p) != tuple(q):
            steps = []
            for d in range(3):
                if p[d] != q[d]:
                    r = list(p)
                    r[d] += 1 if q[d] > p[d] else -1
                    steps.append((float(phi[tuple(r)]), r))
            p = min(steps)[1]
            out.append(tuple(p))
    return out


def join_pieces(phi: np.ndarray, level: float, join_below: float, depth: float):
    """(values, facts): ``phi`` with the samples of the lowest-saddle paths between pieces of ``phi < level``
    (saddles below ``join_below``, see :func:`piece_saddles`) set to at most ``level − depth``; facts: the
    number of pieces, of joins, their saddle values, the samples set.  ``phi`` itself is not changed."""
    phi = np.asarray(phi, dtype=np.float64)
    sad = piece_saddles(phi, level, join_below)
    values = phi
    facts = {"pieces": int(len(sad["sizes"])), "joins": len(sad["edges"]),
             "join_saddles": [round(e[0], 6) for e in sad["edges"]], "join_samples": 0}
    if not sad["edges"]:
        return values, facts
    values = phi.copy()
    shape = phi.shape
    n_set = 0
    for w, a, b, p, q in sad["edges"]:
        half_a = _descend(p, a, sad["labels"], sad["basins"], phi, w)
        half_b = _descend(q, b, sad["labels"], sad["basins"], phi, w)
        path = [tuple(int(c) for c in np.unravel_index(f, shape)) for f in half_a[::-1] + half_b]
        for s in _six_connected(path, phi):
            if values[s] > level - depth:
                values[s] = level - depth
                n_set += 1
    facts["join_samples"] = n_set
    return values, facts
