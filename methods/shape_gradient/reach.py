"""Reaching the samples: a post-step that moves the mesh to the surface the samples say is nearer than it.

Why: every sample q of a signed distance says that the surface passes |φ(q)| from q — the sphere of that radius
around q touches it.  Where the mesh's distance |d_Γ(q)| is larger than |φ(q)| by more than noise explains, the
mesh has lost a part of the data there: a crevice narrower than a voxel that every sample sees as inside (a gap
between lips, between an ear and the head), or the stump of a limb thinner than the grid that the flow could not
grow, or a tip the trilinear zero set rounds off.  φ = 0 does not show such a part, so the flow, which follows the
zero set, has no force towards it; the samples' spheres do (the observation Reach for the Spheres builds its
surface from, here on both sides of the surface).  Where that sphere touches the surface is the sample's foot
point q − φ(q) ∇φ/|∇φ| (∇φ by central differences of the raw samples, ``tips.sample_gradients``; the exact
closest point of a distance); the mesh vertex nearest it (of the closest face, largest barycentric weight) moves
there — the largest move wins where several samples pick one vertex; a few rounds, each reading the moved mesh
again.

Only samples on the same side of the mesh as φ says (a sample the mesh puts on the wrong side is a different error
— a filled gap — that moving one closest point does not mend), in the band |φ| < ``choose.BAND_VOXELS`` voxels,
off by more than ``choose.agree_limit`` (half a voxel plus three noise stds), and at most
:data:`REACH_MAX_VOXELS` from the mesh, which is also how far a vertex may move in all: a detail the mesh missed,
not a body it lost (two balls of which the start kept one stay one ball, flagged by the suite's checks, not a ball
with spikes reaching for the other).  On a noisy volume a sample counts only with another one among its 26
neighbours (``lone=False``): a missed detail is seen by a few samples, while where the mesh is off by a few tenths of
a voxel (common under noise) noise alone lifts single samples past the limit, each of which would pull a vertex a
voxel off.  A mesh that agrees with every sample does not move.  Distances are read as φ/g with the tip
extension's scale g (1 for a distance volume).
"""

from __future__ import annotations

import numpy as np
import trimesh

from .choose import agree_limit, band_samples, mesh_distances
from .tips import distance_scale, sample_gradients

__all__ = ["reach_samples", "REACH_ROUNDS", "REACH_MAX_VOXELS"]

#: rounds of moves, each reading the moved mesh's distances again (a crevice deeper than one move)
REACH_ROUNDS = 3
#: a detail, not a body: only samples at most this many voxels from the mesh pull it, and no vertex moves farther
#: than this in all rounds — a part the mesh lost whole (a second ball) is not bridged by spikes
REACH_MAX_VOXELS = 3.0


def reach_samples(volume, vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray, noise_voxels: float,
                  keep: callable, rounds: int = REACH_ROUNDS, lone: bool = True) -> tuple[np.ndarray, dict]:
    """The vertices (V, 3) after the moves (see the module docstring), and counts for ``info['reach']``:
    ``flagged`` (samples off by more than the limit, first round), ``moved`` (vertices moved), ``rounds`` run,
    ``max_move_voxels``, ``kept_back``.  ``lone``: a flagged sample with no flagged neighbour counts (clean
    volumes) or not (noisy ones).  ``keep(xq, x)`` → (xq, kept back, ok) puts back the moves that made faces
    meet; a round it cannot repair ends the step (its moves undone)."""
    h = volume.h
    x = np.asarray(vertices, float).copy()
    f = np.asarray(faces, np.int64)
    stats = {"flagged": 0, "moved": 0, "rounds": 0, "max_move_voxels": 0.0, "kept_back": 0,
             "limit_voxels": agree_limit(noise_voxels)}
    sel, points, phi = band_samples(volume)
    if not len(sel):
        return x, stats
    phi = phi / distance_scale(volume, x, normals, h)
    moved = np.zeros(len(x), bool)
    x0 = x.copy()
    for r in range(rounds):
        d = mesh_distances(volume, sel, points, x, f)
        off = ((np.sign(d) == np.sign(phi)) & (np.abs(d) - np.abs(phi) > stats["limit_voxels"])
               & (np.abs(d) <= REACH_MAX_VOXELS))
        if not lone and off.any():
            off[off] = _has_flagged_neighbour(sel[off], volume.shape)
        if r == 0:
            stats["flagged"] = int(off.sum())
        if not off.any():
            break
        grad = sample_gradients(volume.values, np.stack(np.unravel_index(sel[off], volume.shape), axis=1),
                                np.asarray(volume.spacing, float) * np.ones(3))
        grad /= np.maximum(np.linalg.norm(grad, axis=1, keepdims=True), 1e-300)
        foot = points[off] - (phi[off] * h)[:, None] * grad                       # where q's sphere touches Γ
        mesh = trimesh.Trimesh(x, f, process=False)
        near, _, face = trimesh.proximity.closest_point(mesh, foot)
        bary = trimesh.triangles.points_to_barycentric(mesh.triangles[face], near)
        vert = f[face, np.argmax(bary, axis=1)]
        move = foot - x[vert]
        order = np.argsort(np.einsum("ij,ij->i", move, move))                    # the largest move is set last
        xq = x.copy()
        xq[vert[order]] = x[vert[order]] + move[order]
        total = xq - x0                                        # no vertex farther than REACH_MAX_VOXELS in all
        length = np.linalg.norm(total, axis=1) / (REACH_MAX_VOXELS * h)
        far = length > 1.0
        xq[far] = x0[far] + total[far] / length[far, None]
        xq, kept, ok = keep(xq, x)
        stats["rounds"] = r + 1
        if not ok:
            break
        stats["kept_back"] += int(kept)
        moved |= np.any(xq != x, axis=1)
        x = xq
    stats["moved"] = int(moved.sum())
    stats["max_move_voxels"] = float(np.linalg.norm(x - x0, axis=1).max() / h) if len(x) else 0.0
    return x, stats


_NEIGHBOURS = np.stack(np.meshgrid(*[np.arange(-1, 2)] * 3, indexing="ij"), -1).reshape(-1, 3)
_NEIGHBOURS = _NEIGHBOURS[np.any(_NEIGHBOURS != 0, axis=1)]          # the 26 around a sample


def _has_flagged_neighbour(flat: np.ndarray, shape) -> np.ndarray:
    """For each of the grid samples ``flat`` (flat indices), whether another of them is among its 26 neighbours."""
    ijk = np.stack(np.unravel_index(flat, shape), axis=1)
    around = ijk[:, None, :] + _NEIGHBOURS
    on_grid = ((around >= 0) & (around < np.asarray(shape))).all(-1)
    idx = np.ravel_multi_index(tuple(np.clip(around, 0, np.asarray(shape) - 1).transpose(2, 0, 1)), shape)
    return (np.isin(idx, flat) & on_grid).any(axis=1)
