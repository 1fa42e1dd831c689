"""The field's protocol: a mesh phantom normalised and sampled as the papers that benchmark meshing of
signed-distance grids do, so that a row of the suite can be set beside their tables (docs/PHANTOMS.md).

``field:NAME`` is the mesh of the phantom ``NAME`` (a real shape such as ``bunny``, or ``mesh:PATH``) with

* **the papers' normalisation**, gpytoolbox's ``normalize_points``: every coordinate minus its minimum, divided
  by the largest coordinate so obtained (the bounding box's longest side becomes 1), then each axis centred on
  its half-extent (the box centred at 0) — Reach for the Arcs, ``scripts/fig_many-shapes-experiment.py``
  (``V_gt = gpy.normalize_points(V_gt)``; it then rotates each shape at random, which the suite does not).
  ``?scale=1.5`` multiplies by 1.5 afterwards, as Carrera et al.'s ``scripts/many-shapes-experiment.py`` does
  (``gpy.normalize_points(V) * 1.5``);
* **the papers' grid values**: the exact signed distance at every grid point, computed as the papers compute it
  (``gpytoolbox.signed_distance``: libigl's AABB distance, the sign from the fast winding number) — the suite's
  own mesh volume is exact within 3h of the surface only.

The grid itself is the run's: with ``extent = 1`` and N points per axis it is the papers' (n + 1)³ points over
[−1, 1]³ of Reach for the Arcs for N = n + 1 (``np.linspace(-1, 1, n + 1)`` per axis) and Carrera et al.'s
``build_grid((res, res, res))`` (libigl's ``igl::grid`` scaled to [−1, 1]³) for N = res; only the order of
the points differs (the suite's array axis 0 is x).  The truth (closest points, samples, curvature) is the
normalised mesh, exactly as for any :class:`~phantoms.mesh.MeshPhantom`.

A mesh whose parts cross or nest is, as for every mesh phantom, first replaced by the boundary of its
winding-number ≥ ½ solid (:mod:`phantoms.mesh.resolve`).  The papers take the fast winding number's sign too —
the same solid — but their distance is to every sheet of the raw mesh, inner ones included, so inside an overlap
their grid values dip towards sheets that are no surface; the suite's grid, samples and metrics all use the
solid's boundary, so the values, the truth and the zero level set are one surface.
"""

from __future__ import annotations

import numpy as np

from geometry.errors import InputError

from .base import DEFAULT_EXTENT, DEFAULT_N, check_extent, check_n, grid_volume
from .mesh import MeshPhantom
from .volume import Volume, check_memory

__all__ = ["FIELD_PREFIX", "FieldPhantom", "field_normalize", "parse_field_spec"]

FIELD_PREFIX = "field:"
#: the scales the papers use after normalising to a unit box (Reach for the Arcs 1, Carrera et al. 1.5)
_OPTIONS = {"scale"}


def parse_field_spec(spec: str) -> tuple[str, float]:
    """``(inner phantom name, scale)`` of ``field:NAME[?scale=S]``; InputError for a malformed spec (an unknown
    or repeated option, a scale that is not a positive number, no name)."""
    if not spec.startswith(FIELD_PREFIX):
        raise InputError(f"{spec!r} is not a field-protocol phantom ({FIELD_PREFIX}NAME)")
    body = spec[len(FIELD_PREFIX):]
    inner, _, query = body.partition("?")
    scale = 1.0
    given: set[str] = set()
    for item in filter(None, query.split("&")):
        key, eq, value = item.partition("=")
        if key not in _OPTIONS or not eq:
            raise InputError(f"phantom {spec!r}: unknown option {item!r}; valid: scale=S (1.5: Carrera et al.)")
        if key in given:                 # which one would count is a guess: refused, as volume: does
            raise InputError(f"phantom {spec!r}: option {key!r} is given twice")
        given.add(key)
        try:
            scale = float(value)
        except ValueError:
            raise InputError(f"phantom {spec!r}: scale must be a number, got {value!r}") from None
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"phantom {spec!r}: scale must be positive, got {value!r}")
    if not inner:
        raise InputError(f"phantom {spec!r}: name a mesh phantom after {FIELD_PREFIX} (e.g. field:bunny)")
    return inner, scale


def field_normalize(vertices, scale: float = 1.0) -> np.ndarray:
    """gpytoolbox's ``normalize_points`` (longest bounding-box side 1, box centred at 0), times ``scale``,
    in the same order of operations (so the same floating-point result)."""
    v = np.array(vertices, dtype=np.float64)
    v -= v.min(axis=0)
    v = v / np.max(v)
    v -= 0.5 * v.max(axis=0)
    return v * scale if scale != 1.0 else v


class FieldPhantom(MeshPhantom):
    """A mesh phantom under the field's protocol (see the module docstring).

    Parameters
    ----------
    inner : MeshPhantom
        The phantom whose mesh is used (its own normalisation is undone first).
    scale : float
        Longest bounding-box side after normalisation (1: Reach for the Arcs; 1.5: Carrera et al.).
    name : str
        The phantom's name (``field:...``).
    """

    truth_note = "ground truth = the input mesh normalised as the papers do (unit bounding box × scale)"
    _check_crossing = False      # its faces are the inner phantom's, resolved there (a similarity keeps them apart)

    def __init__(self, inner: MeshPhantom, scale: float = 1.0, *, name: str):
        raw = inner.vertices / inner.scale + inner.centre
        super().__init__(field_normalize(raw, scale), inner.faces, name=name, normalize=False,
                         description=f"{inner.description}; the field's protocol (longest side {scale:g}, centred)",
                         crease_angle_deg=inner.crease_angle_deg, source=inner.source)
        self.field_scale = float(scale)
        self.resolution = inner.resolution
        if inner.resolution is not None:
            self.truth_note = f"{self.truth_note}; {inner.resolution.note()}"
        self.shape_kind = inner.shape_kind                   # the same shape, rescaled

    @property
    def params(self) -> dict:
        p = super().params
        p["field_scale"] = self.field_scale
        return p

    def _exact_sdf(self):
        """The papers' signed distance (gpytoolbox: AABB distance, winding-number sign), trees built once."""
        import gpytoolbox as gpy

        v, f = self.vertices, self.faces.astype(np.int32)
        tree = gpy.squared_distance_precompute(v, f)
        bvh = gpy.fast_winding_number_precompute(v, f)
        return lambda p: gpy.signed_distance(np.ascontiguousarray(p, float), v, f, cpp_aabb=tree, fwn_bvh=bvh)[0]

    def volume(self, n: int = DEFAULT_N, extent: float = DEFAULT_EXTENT, variant: str = "sdf") -> Volume:
        """The exact signed distance at every point of the n³ grid over [−extent, extent]³."""
        if variant != "sdf":
            raise InputError(f"phantom {self.name!r} is a mesh: only variant 'sdf' exists (got {variant!r})")
        n, extent = check_n(n), check_extent(extent)
        key = ("field", n, extent)
        if key not in self._volume_cache:
            self._volume_cache.clear()
            check_memory((n, n, n), 3, what=f"the N = {n} volume of phantom {self.name!r}")
            self._volume_cache[key] = grid_volume(self._exact_sdf(), n, extent).values
        spacing = 2.0 * extent / (n - 1)
        return Volume(self._volume_cache[key].copy(), origin=[-extent] * 3, spacing=spacing)
