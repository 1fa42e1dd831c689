"""Named real shapes, loaded at run time from data shipped inside installed packages.

Nothing is downloaded and nothing is copied into this repository:

* ``bunny`` – the Stanford bunny of pymeshlab's sample meshes (``pymeshlab/tests/sample_meshes/bunny.obj``,
  28,088 vertices, 56,172 faces, watertight, genus 0); pymeshlab is a core dependency.
* ``cortex`` – the fsaverage5 pial surface of the left hemisphere shipped with nilearn
  (``nilearn/datasets/data/fsaverage5/pial_left.gii.gz``, 10,242 vertices, watertight, genus 0).
* ``brain_mri`` – the MNI152 T1 template (ICBM 2009a, 1 mm) shipped with nilearn, a real MRI volume:
  intensities scaled to [0, 1], thresholded at 0.2 (nilearn's own brain-mask threshold), largest
  connected component, holes filled → brain mask → signed distance (``phantoms.io.mask_to_sdf``, 1 mm) →
  trilinear resampling onto the suite's grid.  There is no analytic truth: the ground truth is the
  marching-cubes surface (level 0) of the full-resolution signed distance volume (attribute
  ``truth_note``), a :class:`MeshPhantom`.

nilearn is an optional dependency (``pip install -e ".[real]"``; the ``dev`` extra includes it).

``mesh:PATH`` names any closed triangle mesh file trimesh reads (OBJ, PLY, STL, OFF, GLB, ...).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from geometry.errors import InputError

from .base import DEFAULT_EXTENT, DEFAULT_N, as_points, check_n, grid_volume
from .mesh import MeshPhantom, load_mesh
from .volume import Volume

__all__ = ["REAL_SHAPES", "get_real_phantom", "get_mesh_file_phantom", "get_volume_phantom", "Bunny", "Cortex",
           "BrainMRI", "bunny_path", "cortex_path", "mni152_t1_path"]


def _package_dir(package: str, extra_hint: str) -> Path:
    """Directory of an installed package without importing it (nilearn's import costs seconds)."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        raise InputError(f"the data of this phantom ships with the Python package {package!r}, which is not "
                         f"installed: {extra_hint}")
    return Path(list(spec.submodule_search_locations)[0])


_NILEARN_HINT = 'pip install -e ".[real]"  (or: pip install nilearn)'


def _data_file(package: str, rel: str, hint: str) -> Path:
    path = _package_dir(package, hint) / rel
    if not path.is_file():
        raise InputError(f"{package} is installed but {rel} is missing from it ({path}); "
                         f"reinstall it: {hint}")
    return path


def bunny_path() -> Path:
    return _data_file("pymeshlab", "tests/sample_meshes/bunny.obj", "pip install pymeshlab")


def cortex_path() -> Path:
    return _data_file("nilearn", "datasets/data/fsaverage5/pial_left.gii.gz", _NILEARN_HINT)


def mni152_t1_path() -> Path:
    return _data_file("nilearn", "datasets/data/mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz", _NILEARN_HINT)


class Bunny(MeshPhantom):
    name = "bunny"
    shape_kind = "smooth solid"
    description = "Stanford bunny (pymeshlab sample mesh, 28k vertices, genus 0): deep concavities"
    # class-level facts for listings (instances recompute them from the mesh)
    genus = 0
    has_creases = True          # 15 edges with a dihedral angle above 60°
    data = "pymeshlab (core dependency)"

    def __init__(self, crease_angle_deg: float = 60.0):
        path = bunny_path()
        v, f = load_mesh(path)
        super().__init__(v, f, crease_angle_deg=crease_angle_deg, source="pymeshlab:tests/sample_meshes/bunny.obj")


class Cortex(MeshPhantom):
    name = "cortex"
    shape_kind = "smooth solid"
    description = "fsaverage5 pial surface, left hemisphere (nilearn, 10k vertices, genus 0): sulci"
    genus = 0
    has_creases = True          # 682 edges above 60° (sulcal fundi and gyral crowns at this resolution)
    data = 'nilearn (pip install -e ".[real]")'

    def __init__(self, crease_angle_deg: float = 60.0):
        import nibabel as nib

        path = cortex_path()
        try:
            v, f = nib.load(str(path)).agg_data()
        except Exception as exc:
            raise InputError(f"{path}: cannot read the GIFTI surface: {exc}") from None
        super().__init__(np.asarray(v, float), np.asarray(f, np.int64), crease_angle_deg=crease_angle_deg,
                         source="nilearn:datasets/data/fsaverage5/pial_left.gii.gz")


class BrainMRI(MeshPhantom):
    """The MNI152 T1 template as a level-set volume; truth = marching cubes of its full-resolution SDF.

    ``volume()`` samples the *MRI-derived* signed distance (trilinear resampling of the 1 mm
    ``mask_to_sdf`` volume, in the normalised coordinates), not the distance to the truth mesh;
    ``sdf``/``truth`` are the exact distance to the truth mesh like any :class:`MeshPhantom`.
    The 1 mm distance volume covers the brain's bounding box plus 6 voxels; beyond it the resampled
    distance continues as (value at the nearest point of that box) + (distance to the box): an upper
    bound, continuous and growing outward.
    """

    name = "brain_mri"
    shape_kind = "smooth solid"
    description = ("MNI152 T1 template (nilearn, 1 mm): brain mask (T1 > 0.2) -> signed distance; "
                   "truth = marching cubes of the full-resolution volume")
    genus = 0
    has_creases = True          # marching-cubes terraces of the 1 mm mask: 1027 edges above 60°
    data = 'nilearn (pip install -e ".[real]")'
    truth_note = ("no analytic truth: scored against the marching-cubes surface (level 0) of the "
                  "full-resolution (1 mm) signed distance volume of the thresholded MNI152 T1 brain mask")

    def __init__(self, threshold: float = 0.2, crease_angle_deg: float = 60.0):
        import nibabel as nib
        from scipy import ndimage
        from skimage.measure import marching_cubes

        from .io import _origin_spacing_from_affine
        from .masks import mask_to_sdf

        self.threshold = float(threshold)
        if not 0.0 < self.threshold < 1.0:
            raise InputError(f"brain_mri threshold must be in (0, 1) (a fraction of the maximum intensity); "
                             f"got {threshold}")
        path = mni152_t1_path()
        img = nib.as_closest_canonical(nib.load(str(path)))
        t1 = np.asarray(img.dataobj, dtype=np.float64)
        origin, spacing = _origin_spacing_from_affine(img.affine, path)
        t1 /= t1.max()
        mask = t1 > self.threshold
        lab, n = ndimage.label(mask)
        if n == 0:
            raise InputError(f"brain_mri: no voxel above threshold {self.threshold}")
        mask = lab == (np.argmax(np.bincount(lab.ravel())[1:]) + 1)
        mask = ndimage.binary_fill_holes(mask)
        # crop to the brain's bounding box plus a margin of outside voxels (the mask reaches the lower
        # face of the field of view at the brain stem: the margin closes the surface there)
        margin = 6
        nz = np.argwhere(mask)
        lo, hi = nz.min(0), nz.max(0) + 1
        mask = np.pad(mask[lo[0]:hi[0], lo[1]:hi[1], lo[2]:hi[2]], margin)
        origin = origin + (lo - margin) * spacing
        self.mri = mask_to_sdf(mask, origin, spacing)             # Volume in mm, negative inside
        v, f, _, _ = marching_cubes(self.mri.values, 0.0, spacing=tuple(self.mri.spacing),
                                    allow_degenerate=False)
        v += self.mri.origin
        self.voxel_mm = float(spacing.min())
        super().__init__(v, f, crease_angle_deg=crease_angle_deg,
                         source="nilearn:datasets/data/mni_icbm152_t1_tal_nlin_sym_09a_converted.nii.gz")
        # curvature of the truth over 2 voxels (docs/METRICS.md's 2h neighbourhood; MC slivers)
        self._curv_radius = 2.0 * self.voxel_mm * self.scale

    @property
    def params(self) -> dict:
        p = super().params
        p["threshold"] = self.threshold
        return p

    def mri_sdf(self, points) -> np.ndarray:
        """The MRI-derived signed distance at world (normalised) points (trilinear, see the class doc)."""
        p = as_points(points)
        q = p / self.scale + self.centre                          # back to mm
        lo, hi = self.mri.lower, self.mri.upper
        qc = np.clip(q, lo, hi)
        out = np.linalg.norm(q - qc, axis=1)
        return (self.mri(qc, clamp=True) + out) * self.scale

    def volume(self, n: int = DEFAULT_N, extent: float = DEFAULT_EXTENT, variant: str = "sdf") -> Volume:
        if variant != "sdf":
            raise InputError(f"phantom {self.name!r} is an MRI volume: only variant 'sdf' exists "
                             f"(got {variant!r})")
        n = check_n(n)
        return grid_volume(self.mri_sdf, n, extent)


REAL_SHAPES: dict[str, type[MeshPhantom]] = {cls.name: cls for cls in (Bunny, Cortex, BrainMRI)}

_CACHE: dict = {}
_VOLUME_CACHE: dict = {}


def _cached(key, name: str, build) -> MeshPhantom:
    """``_CACHE[key]``, built by ``build()`` the first time; a TypeError (bad parameters) is an InputError."""
    if key not in _CACHE:
        try:
            _CACHE[key] = build()
        except TypeError as exc:
            raise InputError(f"bad parameters for phantom {name!r}: {exc}") from None
    return _CACHE[key]


def get_mesh_file_phantom(name: str, path, **params) -> MeshPhantom:
    """The phantom of a closed mesh file (``name`` is its phantom name, ``mesh:PATH``); cached per process
    and file version (path and modification time), like the named shapes."""
    path = Path(path).expanduser()
    try:
        stamp = path.stat().st_mtime_ns
    except OSError:
        stamp = None
    key = (name, str(path.resolve()) if stamp is not None else str(path), stamp, tuple(sorted(params.items())))
    return _cached(key, name, lambda: MeshPhantom.from_file(path, name=name, **params))


def _stamp(path: Path):
    """A file's (or a DICOM folder's files') version: modification times and sizes."""
    try:
        if path.is_dir():
            return tuple(sorted((p.name, p.stat().st_mtime_ns, p.stat().st_size) for p in path.iterdir()))
        st = path.stat()
        return (st.st_mtime_ns, st.st_size)
    except OSError:
        return None


def get_volume_phantom(spec: str, name: str | None = None):
    """The phantom of a ``volume:PATH[?options]`` spec (:class:`phantoms.user.VolumePhantom`); cached per
    process and file version (the image's and the truth file's modification times and sizes)."""
    from .user import VolumePhantom, parse_spec

    path, opts = parse_spec(spec)
    files = [Path(path).expanduser()] + ([Path(opts["truth"]).expanduser()] if "truth" in opts else [])
    key = (spec, name, tuple(_stamp(p) for p in files))
    if key not in _VOLUME_CACHE:
        if len(_VOLUME_CACHE) >= 4:                         # user volumes can be large: keep the last few
            _VOLUME_CACHE.pop(next(iter(_VOLUME_CACHE)))
        _VOLUME_CACHE[key] = VolumePhantom(spec, name=name)
    return _VOLUME_CACHE[key]


def get_real_phantom(name: str, **params) -> MeshPhantom:
    """A named real shape; instances are cached per process and parameters (loading, curvature and the
    grid volume are then computed once)."""
    if name not in REAL_SHAPES:
        raise InputError(f"unknown real shape {name!r}; valid: {', '.join(REAL_SHAPES)}")
    return _cached((name, tuple(sorted(params.items()))), name, lambda: REAL_SHAPES[name](**params))
