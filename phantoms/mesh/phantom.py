"""Mesh-backed phantoms: any closed triangle mesh as a phantom whose ground truth is the mesh itself.

:class:`MeshPhantom` centres the mesh on its minimum bounding sphere and scales it uniformly so that
sphere has radius 1.5 (inside the paper's initial sphere of radius 2 and the default grid [−2.5, 2.5]³).  It then
offers the same interface as the analytic phantoms (``phantoms/analytic.py``):

* ``truth(points)`` – **exact** closest point on the mesh (point-to-triangle, not point-to-vertex),
  unsigned and signed distance, outward normal, mean/Gaussian curvature and distance to the nearest
  crease;
* ``sdf(points)`` – exact signed distance at arbitrary points (:mod:`phantoms.mesh.index`);
* ``volume(n, extent)`` – the exact signed distance on an n³ grid (:mod:`phantoms.mesh.grid_sdf`);
* ``sample_surface(n, seed)`` – seeded, area-uniform points on the mesh with their (face) normals.

Validation
    The mesh must be watertight (every edge in exactly two faces), consistently oriented
    (:mod:`geometry.topology`); an inward-oriented mesh is flipped (outward normals enclose a positive
    volume).  A mesh whose parts cross (:mod:`geometry.intersections`) or nest with the same orientation does not
    bound one solid as it is — the pseudonormal sign reads *outside* inside the body near an inner sheet — and is
    replaced by the boundary of its winding-number ≥ ½ solid (:mod:`phantoms.mesh.resolve`); ``resolution``
    says what changed (None when nothing did), and the description says it too.

Curvature
    H and K at the mesh vertices by the suite's estimator — ``geometry.paraboloid_curvature`` over every
    vertex within ``curvature_radius`` (default twice the median edge length; at least the 1-ring) with
    area-weighted vertex normals — interpolated barycentrically at the closest point.

Creases
    Edges whose adjacent face normals differ by more than ``crease_angle_deg`` (default 60°) are creases;
    ``crease_distance`` is the Euclidean distance from the closest point to the nearest crease edge
    (``inf`` when the mesh has none) and H, K are NaN on a crease, as for the analytic phantoms.

The ``paper`` variant (the paper's printed polynomial) does not exist for a mesh: asking for it raises
:class:`InputError`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.closest import FACE
from geometry.errors import InputError
from geometry.mesh import sample_surface, signed_volume
from geometry.topology import connected_components, directed_edge_repeats, edge_face_counts, euler_characteristic, genus

from ..base import (
    DEFAULT_EXTENT,
    DEFAULT_N,
    Phantom,
    Truth,
    arc_positions,
    as_points,
    check_extent,
    check_n,
    check_sample_count,
)
from ..volume import Volume, check_memory
from .grid_sdf import signed_distance_grid
from .index import TriangleIndex
from .resolve import Resolution, resolve_if_needed
from .segments import SegmentIndex

__all__ = ["MeshPhantom", "load_mesh", "TARGET_RADIUS"]

#: radius of the bounding sphere of every mesh phantom after normalisation
TARGET_RADIUS = 1.5


def load_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of a triangle mesh file trimesh can read; coincident vertices are merged."""
    import trimesh

    path = Path(path)
    if not path.exists():
        raise InputError(f"no such mesh file: {path}")
    if path.is_dir():
        raise InputError(f"{path} is a directory, not a mesh file")
    try:
        mesh = trimesh.load(str(path), force="mesh", process=True)
    except Exception as exc:  # trimesh raises many types (ValueError, KeyError, NotImplementedError, ...)
        raise InputError(f"{path}: cannot read a triangle mesh: {type(exc).__name__}: {exc}") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError(f"{path}: no triangles found (a point cloud or an empty scene?)")
    return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)


def _bounding_sphere(v: np.ndarray) -> tuple[np.ndarray, float]:
    """Minimum enclosing sphere (centre, radius) of the vertices (trimesh.nsphere, on the hull)."""
    from trimesh.nsphere import minimum_nsphere

    centre, radius = minimum_nsphere(v)
    centre = np.asarray(centre, float)
    # minimum_nsphere is exact to its solver's tolerance: make the radius enclose every vertex
    radius = float(np.linalg.norm(v - centre, axis=1).max())
    return centre, radius


def _checked_arrays(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """(vertices float64 (V, 3), faces int64 (F, 3)) or InputError naming what is wrong."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3 or len(v) < 4:
        raise InputError(f"mesh vertices must have shape (V >= 4, 3); got {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or len(f) < 4:
        raise InputError(f"mesh faces must be triangles of shape (F >= 4, 3); got {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        raise InputError(f"mesh faces must be integer vertex indices; got dtype {f.dtype}")
    f = f.astype(np.int64)
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"mesh faces index vertices outside 0..{len(v) - 1}")
    if not np.isfinite(v).all():
        raise InputError("mesh vertices contain NaN or inf")
    return v, f


def _check_closed(f: np.ndarray, nv: int) -> None:
    """Watertight (every undirected edge in exactly two faces) and consistently oriented."""
    if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])):
        raise InputError("mesh has faces that repeat a vertex; clean the mesh (merge/remove degenerate faces)")
    _, counts = edge_face_counts(f, nv)
    boundary = int((counts == 1).sum())
    nonmanifold = int((counts > 2).sum())
    if boundary or nonmanifold:
        raise InputError(
            f"mesh is not watertight: {boundary} boundary edges (in one face) and {nonmanifold} "
            "non-manifold edges (in three or more faces); a mesh phantom needs a closed surface — "
            "fill the holes first (e.g. pymeshlab meshing_close_holes)")
    repeats = directed_edge_repeats(f, nv)
    if repeats:
        raise InputError(f"mesh orientation is inconsistent: {repeats} edges are "
                         "traversed twice in the same direction; fix the face winding first")


class MeshPhantom(Phantom):
    """A phantom whose true surface is a closed triangle mesh (see the module docstring).

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        The mesh's vertex positions.
    faces : array_like of int, shape (F, 3)
        Its triangles; the mesh must be watertight (every edge in exactly two faces) with a consistent
        orientation.  An inward-oriented mesh is flipped.
    name, description : str, optional
        For listings and result records.
    normalize : bool
        Centre on the minimum bounding sphere and scale it to radius :data:`TARGET_RADIUS` (default True).
        The applied map is ``x ↦ (x − centre) · scale`` (attributes ``centre``, ``scale``).
    crease_angle_deg : float
        Dihedral threshold (angle between adjacent face normals) of a crease edge.
    curvature_radius : float, optional
        Neighbourhood radius of the curvature fit (default 2 × median edge length).
    source : str, optional
        Where the mesh came from (shown in ``params``).

    Raises
    ------
    InputError
        A mesh that is not closed and consistently oriented, crosses itself in a way the resolution to its solid
        cannot mend, or has zero extent or zero enclosed volume.
    """

    name = "mesh"
    description = "closed triangle mesh"
    paper_snr_db = None
    #: what the truth is (the mesh itself for a mesh phantom)
    #: the grid volume is certified exact at every grid point within band_cells · h of the surface
    band_cells = 3.0
    _descent_steps = 50
    _passes = 2
    truth_note = "ground truth = the (normalised) input mesh: exact point-to-triangle distances"
    #: whether construction resolves crossing or nested parts (off only for a subclass built from a resolved
    #: phantom's faces; not a parameter, so no configuration can skip it)
    _check_crossing = True
    #: what resolving crossing or nested parts changed (None: the mesh bounded one solid as it was)
    resolution: Resolution | None = None

    def __init__(self, vertices, faces, *, name: str | None = None, description: str | None = None,
                 normalize: bool = True, crease_angle_deg: float = 60.0, curvature_radius: float | None = None,
                 source: str | None = None):
        v, f = _checked_arrays(vertices, faces)
        if name is not None:
            self.name = str(name)
        if description is not None:
            self.description = str(description)
        self.source = source
        self.crease_angle_deg = float(crease_angle_deg)
        _check_closed(f, len(v))
        # orientation: outward normals give a positive enclosed volume (for crossing parts: ∫ w dV > 0)
        enclosed = signed_volume(v, f)
        if enclosed < 0:
            f = f[:, ::-1].copy()
        elif enclosed == 0:
            raise InputError("mesh encloses zero volume")
        if self._check_crossing:
            v, f, self.resolution = resolve_if_needed(v, f)
            if self.resolution is not None:
                self.description = f"{self.description}; {self.resolution.note()}"
                self.truth_note = f"{self.truth_note}; {self.resolution.note()}"

        if normalize:
            centre, radius = _bounding_sphere(v)
            if not radius > 0:
                raise InputError("mesh has zero extent")
            self.centre, self.scale = centre, TARGET_RADIUS / radius
            v = (v - centre) * self.scale
        else:
            self.centre, self.scale = np.zeros(3), 1.0
        self.vertices = v
        self.faces = f
        _, labels = connected_components(f, len(v), by="vertex")
        n_comp = int(len(np.unique(labels[np.unique(f)])))     # components of the referenced vertices
        self.euler = euler_characteristic(f, len(v))
        self.n_components = n_comp
        self.genus = genus(self.euler, n_comp)
        self.index = TriangleIndex(v, f)
        self.face_areas, self.face_normals = self.index.face_areas, self.index.face_normals
        self.edges, self.edge_lengths = self.index.edges, self.index.edge_lengths
        self._find_creases()
        self._curv_radius = curvature_radius
        self._HK = None
        self._volume_cache: dict = {}

    # ------------------------------------------------------------------ construction helpers
    @classmethod
    def from_file(cls, path, **kwargs) -> "MeshPhantom":
        v, f = load_mesh(path)
        kwargs.setdefault("name", f"mesh:{path}")
        kwargs.setdefault("description", f"closed triangle mesh from {Path(path).name}")
        kwargs.setdefault("source", str(path))
        try:
            return cls(v, f, **kwargs)
        except InputError as exc:
            raise InputError(f"{path}: {exc}") from None

    def _find_creases(self) -> None:
        """Crease edges: adjacent face normals differ by more than the threshold."""
        ef = self.index.edge_faces
        cosd = np.einsum("ij,ij->i", self.face_normals[ef[:, 0]], self.face_normals[ef[:, 1]])
        self.dihedral_deg = np.degrees(np.arccos(np.clip(cosd, -1.0, 1.0)))
        crease = self.dihedral_deg > self.crease_angle_deg
        self.crease_edges = self.edges[crease]
        self.has_creases = bool(crease.any())
        if self.has_creases:
            v = self.vertices
            self._creases = SegmentIndex(v[self.crease_edges[:, 0]], v[self.crease_edges[:, 1]])
        self.crease_length = float(self.edge_lengths[crease].sum())

    # ------------------------------------------------------------------ metadata
    @property
    def params(self) -> dict:
        p = {"source": self.source, "vertices": int(len(self.vertices)), "faces": int(len(self.faces)),
             "scale": round(float(self.scale), 8)}
        if self.resolution is not None:
            p["resolved"] = self.resolution.as_dict()
        return p

    # ------------------------------------------------------------------ exact queries
    @property
    def solid_volume(self) -> float:
        """The volume the mesh encloses."""
        from geometry.mesh import signed_volume

        return abs(float(signed_volume(self.vertices, self.faces)))

    def closest(self, points, chunk: int = 20000, max_pairs: int = 1_000_000):
        """Exact closest point on the mesh: ``(closest (P,3), distance (P,), face (P,), bary (P,3),
        feature (P,))`` (certified candidate search, :meth:`phantoms.mesh.index.TriangleIndex.closest`)."""
        return self.index.closest(points, chunk=chunk, max_pairs=max_pairs)

    def sdf(self, points) -> np.ndarray:
        p = as_points(points)
        x, d, face, _, feat = self.closest(p)
        return self.index.sign(p, x, face, feat) * d

    def paper(self, points):
        raise InputError(f"phantom {self.name!r} is a mesh: it has no 'paper' polynomial; use variant 'sdf'")

    def _curvature(self):
        if self._HK is None:
            from geometry import radius_curvature

            v, f = self.vertices, self.faces
            r = self._curv_radius
            if r is None:
                r = 2.0 * float(np.median(self.edge_lengths))
            self.curvature_radius = float(r)
            H, K = radius_curvature(v, f, r)
            self._HK = (np.asarray(H, float), np.asarray(K, float))
        return self._HK

    def crease_distance_at(self, x) -> np.ndarray:
        """Euclidean distance from surface points x to the nearest crease edge (inf without creases); exact,
        chunked against a bucketed KD-tree (:class:`phantoms.mesh.segments.SegmentIndex`)."""
        x = as_points(x)
        if not self.has_creases:
            return np.full(len(x), np.inf)
        return self._creases.distance(x)

    def crease_samples(self, n: int) -> np.ndarray:
        """``n`` points evenly spaced by arc length along the crease edges (dihedral > crease_angle_deg)."""
        if not self.has_creases:
            return np.zeros((0, 3))
        a, b = self._creases.a, self._creases.b
        k, frac = arc_positions(2 * self._creases.half, n)
        return a[k] + frac[:, None] * (b[k] - a[k])

    def inside(self, points) -> np.ndarray:
        """Inside the mesh: fast winding number ≥ ½ (gpytoolbox; Barnes–Hut, exact near the surface)."""
        from gpytoolbox import fast_winding_number

        p = as_points(points)
        return fast_winding_number(p, self.vertices, self.faces.astype(np.int32)) >= 0.5

    def truth(self, points) -> Truth:
        p = as_points(points)
        x, d, face, bary, feat = self.closest(p)
        sign = self.index.sign(p, x, face, feat)
        # normal: the face normal where the closest point is inside a face (exact); on an edge or a vertex
        # the direction to the point (a normal of the non-smooth surface), or the pseudonormal on it
        n = self.face_normals[face].copy()
        off = feat != FACE
        if off.any():
            far = off & (d > 1e-12)
            n[far] = (p[far] - x[far]) * (np.where(sign[far] < 0, -1.0, 1.0) / d[far])[:, None]
            on = off & ~far
            pn = self.index.pseudonormal(face[on], feat[on])
            n[on] = pn / np.maximum(np.linalg.norm(pn, axis=1, keepdims=True), 1e-300)
        H_v, K_v = self._curvature()
        fv = self.faces[face]
        H = np.einsum("ij,ij->i", bary, H_v[fv])
        K = np.einsum("ij,ij->i", bary, K_v[fv])
        crease = self.crease_distance_at(x)
        on_crease = crease <= 1e-12
        H[on_crease] = np.nan
        K[on_crease] = np.nan
        return Truth(x, d, np.where(sign < 0, -d, d), n, H, K, crease)

    def sample_surface(self, n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        n = check_sample_count(n)
        pts, face = sample_surface(self.vertices, self.faces, n, seed)
        return pts, self.face_normals[face].copy()

    # ------------------------------------------------------------------ grid volume
    def volume(self, n: int = DEFAULT_N, extent: float = DEFAULT_EXTENT, variant: str = "sdf") -> Volume:
        """Exact signed distance on an n³ grid over [−extent, extent]³ (the ``paper`` variant does not exist)."""
        if variant != "sdf":
            if variant == "paper":
                raise InputError(f"phantom {self.name!r} is a mesh: it has no 'paper' polynomial; "
                                 "use variant 'sdf'")
            raise InputError(f"unknown variant {variant!r}; mesh phantoms offer only 'sdf'")
        n = check_n(n)
        extent = check_extent(extent)
        key = (n, extent)
        if key not in self._volume_cache:
            self._volume_cache.clear()                           # keep one grid
            # the computation holds 18 bytes a grid point (grid_sdf), then the cached array and its copy: 16
            check_memory((n, n, n), 3, what=f"the N = {n} volume of mesh phantom {self.name!r}")
            self._volume_cache[key] = self.signed_distance_grid(n, extent)
        vals = self._volume_cache[key]
        spacing = 2.0 * extent / (n - 1)
        return Volume(vals.copy(), origin=[-extent] * 3, spacing=spacing)

    def signed_distance_grid(self, n: int, extent: float, stats: dict | None = None) -> np.ndarray:
        """The (n, n, n) signed distance: exact in the band, an upper bound beyond (:mod:`phantoms.mesh.grid_sdf`)."""
        return signed_distance_grid(self.index, n, extent, band_cells=self.band_cells,
                                    descent_steps=self._descent_steps, passes=self._passes,
                                    stats=stats)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r}, vertices={len(self.vertices)}, faces={len(self.faces)})"
