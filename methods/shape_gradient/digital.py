"""Digital topology on a sampled level set: a genus-0 solid grown inside φ < level, and a marching-cubes
field whose surface has the solid's topology.

Why: a sampled level set has the topology of the object only where its features are wider than a voxel.  Two
sulcal banks of a cortex closer than h, or an ear thinner than h, make the region φ < 0 (and the marching-cubes
surface of φ) gain handles and tunnels the object does not have.  FreeSurfer-style topology correction answers
with *homotopic region growing*: start from the deepest inside sample and add inside samples in order of φ
(most negative first), each only if it is a *simple point* — adding it changes neither the number of
components, nor of tunnels, nor of cavities.  The grown solid stays a topological ball (one component, no
handle, no cavity) and takes every inside sample except a few: where the sampled region has a handle, the
growth stops at its thinnest place (the samples with φ closest to 0), which is where the object is most likely
to be separate.

* :func:`homotopic_growth` — that growth (26-connected solid, 6-connected background; the grid's outer layer
  is never added, so the solid's surface is closed inside the box).  Compiled with numba; the simple-point test
  has a pure-Python reference (:func:`is_simple_reference`, scipy labelling) the tests compare it with.
* :func:`homotopic_thinning` — the reverse: samples of a solid removed, highest φ first, each only while it is
  a simple point (the topology is kept; what must stay to close a hole stays).
* :func:`ball_field` — a copy of φ whose marching-cubes surface (scikit-image, Lewiner's topologically consistent
  tables) has the grown solid's topology: samples left out of the solid are set just outside (+ ``eps``·h), samples of
  the solid at or above the level just inside (− ``eps``·h); then marching cubes' ambiguous cells (faces with diagonal
  signs, cubes whose inside or outside corners are not edge-connected) are resolved toward the solid's 26-connectivity,
  first gently (the outside values of a face scaled until the face's asymptotic decider joins the inside corners), then,
  if the surface still has a handle, by clamping the values of the ambiguous cells (inside ≤ −``floor``, outside ≤ δ)
  with ``floor`` growing.  Each attempt is checked (:func:`surface_is_sphere`); the caller receives the first that gives
  one closed genus-0 surface, and which one it was.

Simple points (Bertrand & Malandain 1994): a sample x is simple for a 26-connected solid X with a 6-connected
background iff X ∩ N26*(x) has one 26-component and the background ∩ N18(x) has one 6-component that is
6-adjacent to x.
"""

from __future__ import annotations

import heapq

import numpy as np
from scipy import ndimage

from geometry.compiled import AVAILABLE, jit

__all__ = ["homotopic_growth", "homotopic_thinning", "is_simple_reference", "ball_field", "ambiguous_cells",
           "surface_is_sphere", "NEIGHBOUR_OFFSETS"]

#: the 26 neighbour offsets, in a fixed order (position 13 of the 3×3×3 block is the centre, left out)
NEIGHBOUR_OFFSETS = np.array([(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                              if (i, j, k) != (0, 0, 0)], dtype=np.int64)


def _adjacency(kind: int) -> np.ndarray:
    """(26, 26) padded neighbour lists of the 26 positions under 6- or 26-adjacency (−1 = end)."""
    out = np.full((26, 26), -1, np.int64)
    for a in range(26):
        d = np.abs(NEIGHBOUR_OFFSETS - NEIGHBOUR_OFFSETS[a])
        near = (d.max(axis=1) <= 1) & (d.sum(axis=1) > 0)
        if kind == 6:
            near &= d.sum(axis=1) == 1
        idx = np.flatnonzero(near)
        out[a, :len(idx)] = idx
    return out


_ADJ6, _ADJ26 = _adjacency(6), _adjacency(26)
_L1 = np.abs(NEIGHBOUR_OFFSETS).sum(axis=1)
_N18 = _L1 <= 2          # the 18-neighbourhood (faces and edges)
_FACE6 = _L1 == 1        # the 6 face neighbours
_ALL = np.ones(26, np.bool_)


@jit
def _components(mask, use, adj, face_only, face):
    """Components (under ``adj``) of the positions with mask & use; with face_only, only those containing a
    face neighbour of the centre are counted."""
    seen = np.zeros(26, np.bool_)
    stack = np.empty(26, np.int64)
    count = 0
    for s in range(26):
        if not (mask[s] and use[s]) or seen[s]:
            continue
        seen[s] = True
        top = 0
        stack[0] = s
        touches = face[s]
        while top >= 0:
            p = stack[top]
            top -= 1
            touches = touches or face[p]
            for q in adj[p]:
                if q < 0:
                    break
                if mask[q] and use[q] and not seen[q]:
                    seen[q] = True
                    top += 1
                    stack[top] = q
        if touches or not face_only:
            count += 1
    return count


@jit
def _is_simple(solid, i, j, k, off, adj6, adj26, n18, face, all26):
    inside = np.empty(26, np.bool_)
    outside = np.empty(26, np.bool_)
    for a in range(26):
        v = solid[i + off[a, 0], j + off[a, 1], k + off[a, 2]]
        inside[a] = v
        outside[a] = not v
    if _components(inside, all26, adj26, False, face) != 1:
        return False
    return _components(outside, n18, adj6, True, face) == 1


@jit
def _grow(phi, level, seed, off, adj6, adj26, n18, face, all26):
    n0, n1, n2 = phi.shape
    solid = np.zeros(phi.shape, np.bool_)
    queued = np.zeros(phi.shape, np.bool_)
    si, sj, sk = seed[0], seed[1], seed[2]
    solid[si, sj, sk] = True
    heap = [(phi[si, sj, sk], si, sj, sk)]
    heap.pop()
    for a in range(26):
        u, v, w = si + off[a, 0], sj + off[a, 1], sk + off[a, 2]
        if phi[u, v, w] < level:
            queued[u, v, w] = True
            heap.append((phi[u, v, w], u, v, w))
    heapq.heapify(heap)
    while len(heap) > 0:
        _, i, j, k = heapq.heappop(heap)
        queued[i, j, k] = False
        if solid[i, j, k] or i == 0 or j == 0 or k == 0 or i == n0 - 1 or j == n1 - 1 or k == n2 - 1:
            continue
        if not _is_simple(solid, i, j, k, off, adj6, adj26, n18, face, all26):
            continue            # may become simple later: re-queued when a neighbour joins
        solid[i, j, k] = True
        for a in range(26):
            u, v, w = i + off[a, 0], j + off[a, 1], k + off[a, 2]
            if not solid[u, v, w] and not queued[u, v, w] and phi[u, v, w] < level:
                queued[u, v, w] = True
                heapq.heappush(heap, (phi[u, v, w], u, v, w))
    return solid


def is_simple_reference(block: np.ndarray) -> bool:
    """Pure-Python/scipy reference of the simple-point test: ``block`` is the (3, 3, 3) solid around x (the
    centre's own value is ignored); x is simple for a 26-connected solid / 6-connected background."""
    from scipy import ndimage

    b = np.asarray(block, bool).copy()
    b[1, 1, 1] = False
    n26 = int(ndimage.label(b, structure=np.ones((3, 3, 3)))[1])
    if n26 != 1:
        return False
    outside = ~b
    l1 = np.abs(np.indices((3, 3, 3)) - 1).sum(axis=0)
    outside &= l1 <= 2
    outside[1, 1, 1] = False
    lab, _ = ndimage.label(outside)          # 6-connectivity (the default structure)
    faces = lab[l1 == 1]
    return len(set(faces[faces > 0].tolist())) == 1


def _grow_reference(phi: np.ndarray, level: float, seed) -> np.ndarray:
    """The growth in Python with :func:`is_simple_reference` (small grids; the tests' reference, and the
    fallback without numba)."""
    solid = np.zeros(phi.shape, bool)
    solid[tuple(seed)] = True
    shape = np.asarray(phi.shape)
    heap, queued = [], np.zeros(phi.shape, bool)

    def push(p):
        for o in NEIGHBOUR_OFFSETS:
            q = tuple(np.asarray(p) + o)
            if not solid[q] and not queued[q] and phi[q] < level:
                queued[q] = True
                heapq.heappush(heap, (float(phi[q]), q))
    push(tuple(seed))
    while heap:
        _, p = heapq.heappop(heap)
        queued[p] = False
        if solid[p] or min(p) == 0 or np.any(np.asarray(p) == shape - 1):
            continue
        sl = tuple(slice(c - 1, c + 2) for c in p)
        if not is_simple_reference(solid[sl]):
            continue
        solid[p] = True
        push(p)
    return solid


def homotopic_growth(phi: np.ndarray, level: float = 0.0, *, reference: bool = False) -> np.ndarray:
    """The genus-0 solid grown inside ``phi < level`` (bool array of phi's shape; see the module docstring).

    The seed is the deepest sample of the largest 26-connected part of ``phi < level`` off the grid's outer
    layer (of several objects the largest is kept — not the one with the deepest sample, which may be a small
    fragment: a mis-signed sliver of a flawed mesh's distance field took 16 of 7,476 inside samples); an empty
    array when no such sample is inside.
    ``reference=True`` runs the pure-Python growth (slow; for tests on small grids).
    """
    phi = np.ascontiguousarray(phi, dtype=np.float64)
    if phi.ndim != 3 or min(phi.shape) < 3:
        raise ValueError(f"homotopic_growth: expected a 3-D grid of at least 3 samples per axis, got {phi.shape}")
    core = phi[1:-1, 1:-1, 1:-1]
    labels, n = ndimage.label(core < level, structure=np.ones((3, 3, 3), bool))
    if n == 0:
        return np.zeros(phi.shape, bool)
    largest = 1 + int(np.argmax(np.bincount(labels.ravel())[1:]))
    seed = np.asarray(np.unravel_index(int(np.argmin(np.where(labels == largest, core, np.inf))), core.shape)) + 1
    if reference or not AVAILABLE:
        return _grow_reference(phi, float(level), seed)
    return _grow(phi, float(level), seed.astype(np.int64), NEIGHBOUR_OFFSETS, _ADJ6, _ADJ26, _N18, _FACE6, _ALL)


@jit
def _thin(solid, phi, removable, off, adj6, adj26, n18, face, all26):
    solid = solid.copy()
    queued = np.zeros(solid.shape, np.bool_)
    heap = [(-phi[0, 0, 0], 0, 0, 0)]
    heap.pop()
    idx = np.argwhere(removable & solid)
    for r in range(idx.shape[0]):
        i, j, k = idx[r, 0], idx[r, 1], idx[r, 2]
        queued[i, j, k] = True
        heap.append((-phi[i, j, k], i, j, k))
    heapq.heapify(heap)
    while len(heap) > 0:
        _, i, j, k = heapq.heappop(heap)
        queued[i, j, k] = False
        if not solid[i, j, k] or not _is_simple(solid, i, j, k, off, adj6, adj26, n18, face, all26):
            continue            # may become simple later: re-queued when a neighbour leaves
        solid[i, j, k] = False
        for a in range(26):
            u, v, w = i + off[a, 0], j + off[a, 1], k + off[a, 2]
            if solid[u, v, w] and removable[u, v, w] and not queued[u, v, w]:
                queued[u, v, w] = True
                heapq.heappush(heap, (-phi[u, v, w], u, v, w))
    return solid


def _thin_reference(solid: np.ndarray, phi: np.ndarray, removable: np.ndarray) -> np.ndarray:
    """The thinning in Python with :func:`is_simple_reference` (the tests' reference, the fallback without numba)."""
    solid = solid.copy()
    heap = [(-float(phi[p]), p) for p in map(tuple, np.argwhere(removable & solid))]
    heapq.heapify(heap)
    queued = set(q for _, q in heap)
    while heap:
        _, p = heapq.heappop(heap)
        queued.discard(p)
        if not solid[p] or not is_simple_reference(solid[tuple(slice(c - 1, c + 2) for c in p)]):
            continue
        solid[p] = False
        for o in NEIGHBOUR_OFFSETS:
            q = tuple(int(c) for c in np.asarray(p) + o)
            if solid[q] and removable[q] and q not in queued:
                queued.add(q)
                heapq.heappush(heap, (-float(phi[q]), q))
    return solid


def homotopic_thinning(solid: np.ndarray, phi: np.ndarray, removable: np.ndarray, *,
                       reference: bool = False) -> np.ndarray:
    """``solid`` with its ``removable`` samples taken out, highest ``phi`` first, each only while it is a simple
    point (26-connected solid, 6-connected background): the topology is unchanged, and a removable sample stays
    only where taking it out would open a hole, split the solid or make a cavity.  ``removable`` must not touch
    the grid's outer layer (nor does a solid from :func:`homotopic_growth`)."""
    solid = np.asarray(solid, bool)
    removable = np.asarray(removable, bool) & solid
    if removable.any():
        edge = removable.copy()
        edge[1:-1, 1:-1, 1:-1] = False
        if edge.any():
            raise ValueError("homotopic_thinning: removable samples on the grid's outer layer")
    phi = np.ascontiguousarray(phi, dtype=np.float64)
    if reference or not AVAILABLE:
        return _thin_reference(solid, phi, removable)
    return _thin(np.ascontiguousarray(solid), phi, np.ascontiguousarray(removable), NEIGHBOUR_OFFSETS, _ADJ6,
                 _ADJ26, _N18, _FACE6, _ALL)


# --- a marching-cubes field with the solid's topology ------------------------------------------------------

_CORNERS = np.array([(i, j, k) for i in (0, 1) for j in (0, 1) for k in (0, 1)])
_CUBE_EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if np.abs(_CORNERS[a] - _CORNERS[b]).sum() == 1]


def _edge_components(code: int) -> int:
    """Components of the corners set in ``code`` (8 bits) under the cube's edges."""
    on = [c for c in range(8) if code >> c & 1]
    parent = {c: c for c in on}

    def root(c):
        while parent[c] != c:
            c = parent[c]
        return c
    for a, b in _CUBE_EDGES:
        if a in parent and b in parent:
            parent[root(a)] = root(b)
    return len({root(c) for c in on})


def _ambiguous_code(code: int) -> bool:
    if _edge_components(code) >= 2 or _edge_components(255 - code) >= 2:
        return True
    for ax in range(3):
        for side in (0, 1):
            on = [c for c in range(8) if _CORNERS[c][ax] == side and code >> c & 1]
            if len(on) == 2 and np.abs(_CORNERS[on[0]] - _CORNERS[on[1]]).sum() == 2:
                return True
    return False


_AMBIGUOUS = np.array([_ambiguous_code(c) for c in range(256)])


def ambiguous_cells(inside: np.ndarray) -> np.ndarray:
    """(n0−1, n1−1, n2−1) bool: the grid cells whose sign pattern marching cubes must disambiguate (a face
    with diagonal signs, or inside/outside corners not connected along the cell's edges)."""
    n = [s - 1 for s in inside.shape]
    code = np.zeros(n, np.int64)
    for c, (i, j, k) in enumerate(_CORNERS):
        code |= inside[i:i + n[0], j:j + n[1], k:k + n[2]].astype(np.int64) << c
    return _AMBIGUOUS[code]


def _cell_corners(cells: np.ndarray) -> np.ndarray:
    """Samples that are a corner of at least one marked cell."""
    n = cells.shape
    out = np.zeros(tuple(s + 1 for s in n), bool)
    for i, j, k in _CORNERS:
        out[i:i + n[0], j:j + n[1], k:k + n[2]] |= cells
    return out


def _join_faces(phi: np.ndarray, rounds: int = 4, margin: float = 1.5) -> np.ndarray:
    """Scale down the outside values of faces with diagonal signs until each face's asymptotic decider joins
    its two inside corners (a·c > margin·b·d), the gentlest change that gives marching cubes 26-connectivity
    on faces.

    Only outside values are scaled, by factors in (0, 1): no sample changes sign, so the faces with diagonal
    signs are found once (boolean masks) and each round reads and scales values at those faces only."""
    phi = phi.copy()
    neg = phi < 0
    faces = []                                   # (the four corner views, the candidate faces' indices)
    for ax in range(3):
        o0, o1 = [a for a in range(3) if a != ax]

        def corner(arr, d0, d1):
            sl = [slice(None)] * 3
            sl[o0] = slice(d0, arr.shape[o0] - 1 + d0)
            sl[o1] = slice(d1, arr.shape[o1] - 1 + d1)
            return arr[tuple(sl)]
        views = [corner(phi, 0, 0), corner(phi, 1, 0), corner(phi, 1, 1), corner(phi, 0, 1)]
        signs = [corner(neg, 0, 0), corner(neg, 1, 0), corner(neg, 1, 1), corner(neg, 0, 1)]
        for order in ((0, 1, 2, 3), (1, 2, 3, 0)):
            p, q, r, s = (signs[i] for i in order)
            idx = np.nonzero(p & r & ~q & ~s)
            faces.append(([views[i] for i in order], idx))
    for _ in range(rounds):
        changed = False
        for (p, q, r, s), idx in faces:
            if not len(idx[0]):
                continue
            pv, qv, rv, sv = p[idx], q[idx], r[idx], s[idx]
            bad = pv * rv <= margin * qv * sv
            if bad.any():
                with np.errstate(divide="ignore", invalid="ignore"):
                    f = np.minimum(np.sqrt(pv[bad] * rv[bad] / (margin * qv[bad] * sv[bad])), 1.0) * 0.999
                sel = tuple(i[bad] for i in idx)
                q[sel] = qv[bad] * f        # views into phi (each face's corner is its own sample)
                s[sel] = s[sel] * f
                changed = True
        if not changed:
            break
    return phi


def surface_is_sphere(field: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Marching cubes (index coordinates) of ``field`` at 0 when it is one closed, consistently oriented
    genus-0 surface, else None."""
    from skimage.measure import marching_cubes

    from geometry.topology import is_sphere_like
    try:
        v, f, _, _ = marching_cubes(field, 0.0, method="lewiner", allow_degenerate=False)
    except (ValueError, RuntimeError):
        return None
    f = np.asarray(f, np.int64)
    if not is_sphere_like(f, len(v)):
        return None
    return np.asarray(v, float), f


#: outside-value floors (in h) tried in turn when the gentle face fix leaves a handle (see ball_field)
_CLAMP_FLOORS = (0.2, 0.4, 0.8)


def ball_field(phi: np.ndarray, solid: np.ndarray, h: float, eps: float = 0.05):
    """(field, mesh, how): φ changed so that marching cubes gives the genus-0 surface of ``solid``, the
    (vertices in index coordinates, faces) of that surface, and which attempt gave it ('gentle',
    'clamp <floor>' or, last, 'binary': inside samples −h, outside +eps·h); ``(None, None, 'failed')`` if
    none did.  See the module docstring."""
    base = np.where(solid, phi, np.maximum(phi, eps * h))
    # no sample exactly on the level; a sample above it that the solid holds (a closed pinhole) just inside
    base = np.where(solid, np.where(phi >= 0, -eps * h, np.minimum(base, -1e-6 * h)), base)
    field = _join_faces(base)
    mesh = surface_is_sphere(field)
    if mesh is not None:
        return field, mesh, "gentle"
    cells = _cell_corners(ambiguous_cells(solid))
    for floor in _CLAMP_FLOORS:
        field = base.copy()
        delta = floor / 16.0
        inner = cells & solid
        outer = cells & ~solid
        field[inner] = np.minimum(base[inner], -floor * h)
        field[outer] = np.minimum(base[outer], delta * h)
        mesh = surface_is_sphere(field)
        if mesh is not None:
            return field, mesh, f"clamp {floor:g}"
    field = np.where(solid, -h, eps * h)        # last resort: the solid's samples alone decide
    mesh = surface_is_sphere(field)
    if mesh is not None:
        return field, mesh, "binary"
    return None, None, "failed"
