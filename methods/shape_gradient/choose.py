"""The start choice (``start_choice='auto'``): flow from several genus-0 starts and keep the result that agrees
best with the samples.

Why: no one start suits every shape.  The usual start (φ < 0 grown genus-0) loses a part thinner than a voxel
that every sample misses — a blade, a limb — and the flow cannot grow it back; the carved start
(carved_start.py, with ``hold_carved``) keeps such parts but can fill a gap narrower than a voxel (a sulcus
between its banks), and read at φ < ¼ voxel it keeps the thinnest blades and fills more gaps.  Which one is right
is a fact about the data, and the data can say: every sample near the surface carries its signed distance, so a
candidate surface Γ is scored by the root mean square of d_Γ(q) − φ(q) over the samples q with
|φ(q)| < :data:`BAND_VOXELS` voxels (d_Γ the signed distance to Γ, negative inside).  A lost blade leaves the
samples around it with small φ but a large d_Γ; a filled gap puts samples of positive φ inside Γ; a surface off
by a bias shifts every term.  The band is one fixed set of samples, the same for every candidate, so the scores
compare; noise adds the same variance to each.  The score reads only the input — no truth.

The other starts cost two more flows, so they are tried only where the usual start's result lacks a part of the
data (:func:`lacks_a_part`): some sample lies farther outside Γ than its own distance says, d_Γ(q) − φ(q) above
half a voxel plus three noise stds (a lost limb leaves samples voxels away from Γ).  A disagreement of the other
sign — Γ nearer to, or over, a sample than φ(q) says: a concave crease the trilinear zero set fills, a gap it
closes — is not tried: every other start holds more material than the usual one (the carved hull lies within
φ₀ < 0 ∪ the region no ball reaches, the quarter-voxel level below φ₀ < 0) and ``hold_carved`` only limits inward
moves, so none of them can take material out of a filled crease.

A candidate is scored on the flow's result before the reach to the samples (reach.py, when it is on): the reach
mends single spots, which would hide from the score a start that lost more.

The candidates are flowed one after the other with the same parameters except the start's (:data:`CANDIDATES`);
a candidate whose flow fails is left out (its error recorded); when the usual start's flow fails (a collapse, a
result off the surface), the carved ones are still tried, and its error is the method's only if they fail too.
An error about the input itself (``InputError``) ends the method at once.
"""

from __future__ import annotations

import numpy as np

from geometry.closest import point_mesh_distance
from geometry.raster import grid_winding
from phantoms import Volume

from .carved_start import fine_grid_fits

__all__ = ["band_samples", "mesh_distances", "data_errors", "data_residual", "rms", "lacks_a_part",
           "CANDIDATES", "USUAL_START", "start_settings",
           "BAND_VOXELS", "PREFER_USUAL", "AGREE_VOXELS", "agree_limit", "AGREE_NOISE_STDS",
           "start_candidates", "pick"]

#: the band of samples the residual reads: |φ| below this many voxels
BAND_VOXELS = 1.5

#: the usual result lacks no part of the data when no band sample lies outside it by more than this many voxels ...
AGREE_VOXELS = 0.5
#: ... plus this many noise stds (the estimated noise of the input)
AGREE_NOISE_STDS = 3.0

#: a carved start is kept only where its residual is below the usual start's by this fraction: where they nearly
#: tie (a sphere, an ellipsoid under noise) the usual start's mesh is the smoother one (no held vertices)
PREFER_USUAL = 0.05

#: the start's private settings (no parameter of the method: only the choice sets them) and their usual values:
#: ``carved_start`` grows the genus-0 start from the carved hull (carved_start.py); ``hold_carved`` keeps the flow's
#: inward moves within ``carve_margin`` voxels of the outside samples' empty balls (carve.py); ``start_level``
#: grows the genus-0 start from φ < ``start_level`` voxels
USUAL_START: dict = {"carved_start": False, "hold_carved": False, "carve_margin": 0.25, "start_level": 0.0}

#: (name, start settings replacing :data:`USUAL_START`'s) of the starts tried, the usual one first
CANDIDATES: tuple[tuple[str, dict], ...] = (
    ("usual", {}),
    ("carved", {"carved_start": True, "hold_carved": True, "carve_margin": 0.1}),
    ("carved_level", {"carved_start": True, "hold_carved": True, "carve_margin": 0.1, "start_level": 0.25}),
)


def start_settings(start: dict | None = None) -> dict:
    """:data:`USUAL_START` with ``start``'s values (a candidate's); an unknown key is a programming error."""
    unknown = set(start or {}) - set(USUAL_START)
    if unknown:
        raise ValueError(f"unknown start settings: {sorted(unknown)}")
    return {**USUAL_START, **(start or {})}


def start_candidates(config: dict, volume: Volume) -> tuple[tuple[str, dict], ...]:
    """The candidates :func:`CANDIDATES` to flow for ``volume`` with ``config``, or () for one flow from the
    usual start: the choice needs ``start_choice='auto'``, the genus-0 start of a signed distance (the carved
    hull reads distances) and the refined grid within :data:`~.carved_start.FINE_MAX_SAMPLES`."""
    if (config["start_choice"] != "auto" or config["init"] != "genus0" or config["init_mesh"] is not None
            or volume.kind != "sdf"):
        return ()
    return CANDIDATES if fine_grid_fits(volume.shape) else ()


def pick(residuals: dict) -> str:
    """The candidate kept, from ``{name: residual}`` in the order of :data:`CANDIDATES` (the usual start first,
    when its flow succeeded): the least residual among the others if it is below (1 − :data:`PREFER_USUAL`) × the
    usual one's, else the usual one; without a usual result (its flow failed), the least residual.  A NaN residual
    never wins."""
    names = list(residuals)
    usual = CANDIDATES[0][0]
    others = [n for n in names if n != usual and np.isfinite(residuals[n])]
    if usual not in residuals or not others:
        return usual if usual in residuals or not others else min(others, key=lambda n: residuals[n])
    best = min(others, key=lambda n: residuals[n])
    if not np.isfinite(residuals[usual]) or residuals[best] < (1.0 - PREFER_USUAL) * residuals[usual]:
        return best
    return usual


def band_samples(volume: Volume, band_voxels: float = BAND_VOXELS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The samples q with |φ(q)| < ``band_voxels`` voxels: (flat indices into the grid, positions (Q, 3), φ(q) in
    voxels) — the samples that say where the surface is (each lies |φ(q)| from it)."""
    h = volume.h
    phi = np.asarray(volume.values, float).reshape(-1) / h
    sel = np.flatnonzero(np.abs(phi) < band_voxels)
    origin, spacing = np.asarray(volume.origin, float), np.asarray(volume.spacing, float) * np.ones(3)
    points = origin + np.stack(np.unravel_index(sel, volume.shape), axis=1) * spacing
    return sel, points, phi[sel]


def mesh_distances(volume: Volume, sel: np.ndarray, points: np.ndarray, vertices: np.ndarray,
                   faces: np.ndarray) -> np.ndarray:
    """d_Γ at the grid samples ``sel`` (flat indices, positions ``points``) in voxels: the signed distance to the
    closed mesh, negative inside (its winding number at the sample is not 0, as the fidelity metrics read it)."""
    if not len(sel):
        return np.zeros(0)
    origin, spacing = np.asarray(volume.origin, float), np.asarray(volume.spacing, float) * np.ones(3)
    inside = grid_winding(vertices, faces, origin, spacing, volume.shape).reshape(-1)[sel] != 0
    unsigned = point_mesh_distance(points, vertices, faces) / volume.h
    return np.where(inside, -unsigned, unsigned)


def data_errors(volume: Volume, vertices: np.ndarray, faces: np.ndarray,
                band_voxels: float = BAND_VOXELS) -> np.ndarray:
    """d_Γ(q) − φ(q) in voxels at the :func:`band_samples` q, d_Γ as :func:`mesh_distances` reads it."""
    sel, points, phi = band_samples(volume, band_voxels)
    return mesh_distances(volume, sel, points, vertices, faces) - phi


def data_residual(volume: Volume, vertices: np.ndarray, faces: np.ndarray,
                  band_voxels: float = BAND_VOXELS) -> float:
    """The root mean square of :func:`data_errors`, in voxels; NaN when no sample is in the band."""
    return rms(data_errors(volume, vertices, faces, band_voxels))


def rms(errors: np.ndarray) -> float:
    """The root mean square of ``errors``; NaN when there are none."""
    return float(np.sqrt(np.mean(errors ** 2))) if len(errors) else float("nan")


def lacks_a_part(errors: np.ndarray, noise_voxels: float) -> bool:
    """Whether some sample lies outside the mesh farther than its distance says, d_Γ − φ above
    :data:`AGREE_VOXELS` + :data:`AGREE_NOISE_STDS` noise stds (``errors``: :func:`data_errors`), or there are no
    band samples to tell: the mesh misses a part of the data that a start with more material may hold."""
    return not len(errors) or float(np.max(errors)) > agree_limit(noise_voxels)


def agree_limit(noise_voxels: float) -> float:
    """How far (voxels) a sample may be off the mesh and still agree: :data:`AGREE_VOXELS` plus
    :data:`AGREE_NOISE_STDS` × the noise std (voxels): a right mesh's samples stay within it unless the mesh is
    itself a few tenths of a voxel off there."""
    return AGREE_VOXELS + AGREE_NOISE_STDS * float(noise_voxels)
