"""The real tier: a real segmentation at fine resolution is the reference, its coarse versions are the inputs.

The protocol users trust — *does the mesh of the 2 mm scan match the 1 mm segmentation?* — with data that ships
inside an installed package, nothing downloaded or copied into this repository:

* ``mni_wm`` – white matter of the ICBM 2009a (MNI152 nonlinear symmetric) tissue probability map shipped with
  nilearn (``nilearn/datasets/data/mni_icbm152_wm_tal_nlin_sym_09a_converted.nii.gz``, 1 mm): branching gyral
  stalks (2 pieces, genus 7 in the crop below);
* ``mni_gm`` – grey matter of the same template (``..._gm_...``): a folded thin shell with 41 enclosed pockets
  (genus 125).

**Fine segmentation.**  The map (stored 0–255: probability = value / 255) thresholded at probability 0.5 (more
than half), its largest 26-connected component, cropped to the 60 mm cube centred at MNI (−30, −40, 20) mm (left
parieto-occipital lobe: stalks and folds, genus in the tens), the crop's 26-connected pieces of fewer than 27 voxels
(pieces the cut leaves that are smaller than one voxel of the ×3 input) dropped, padded with 6 outside voxels on
every face: a 72³ mask on the template's own 1 mm grid, world coordinates in mm (RAS+).  :attr:`fine_mask`,
:attr:`fine_origin`, :attr:`fine_spacing`.

**Truth.**  The zero level set of the fine mask's signed distance (:func:`phantoms.masks.mask_to_sdf`: zero
half-way between an inside and an outside voxel centre), extracted by marching cubes — the same reference the
suite builds from a user's label image (``volume:...?truth=LABELS``) and from the MRI (``brain_mri``).  The voxel
surface (the union of the voxel cubes) would be the other choice; it is a staircase whose every edge is a crease, so
curvature and normals mean nothing on it, and the marching-cubes surface lies within ½ voxel of it (vertices on its
faces, corners cut).  Where the mask's inside voxels touch along an edge or at a corner only, the values of the
cell are ±½ voxel and its saddles are exactly 0 — marching cubes then joins some and cuts others, and leaves
non-manifold edges; the distance is lowered by :data:`TIE_BREAK` voxels before marching cubes so that every tie
resolves one way: inside voxels that touch at all are joined (26-connected inside, 6-connected outside — the digital
topology whose components, cavities and Euler characteristic the truth mesh then has, tests/test_phantoms_real_tier.py).

**Inputs.**  :meth:`FineReferencePhantom.coarse_input`, reached through :func:`phantoms.degrade.degrade` with the
degradation steps ``downsample@K`` (K × K × K blocks) and ``thick_slices@K`` (1 × 1 × K blocks; both: K_d × K_d ×
K_d·K_t) plus ``mask`` or ``partial_volume``: the fine mask is averaged over blocks of whole fine voxels — the
exact inside fraction of each coarse voxel (a coarse voxel is the union of its fine voxels), a partial-volume image
— and ``mask`` keeps the coarse voxels more than half inside.  Coarse voxel centres are the centres of their blocks:
origin = fine origin + (K − 1)/2 · fine spacing, spacing = K · fine spacing.  ``blur`` and ``label_noise`` act on the
coarse image as on any phantom's.  The phantoms run on their own grid (a config's N does not apply: the row's N is
the fine grid's largest dimension, its h the coarse spacing).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from geometry.errors import InputError

from .mesh import MeshPhantom
from .real import _NILEARN_HINT, _cached, _data_file
from .volume import Volume

__all__ = ["FINE_SHAPES", "FineReferencePhantom", "MNIWhiteMatter", "MNIGreyMatter", "get_fine_phantom",
           "block_fraction", "coarse_grid", "mni_tissue_path", "TIE_BREAK", "MAX_FACTOR"]

#: voxels subtracted from the fine mask's signed distance before marching cubes: resolves the exact ties of voxels
#: touching along an edge or at a corner as "joined" (module docstring); moves the surface by a millionth of a voxel
TIE_BREAK = 1e-6
#: outside voxels padded on every face of the fine mask; the largest block factor along an axis (a coarse voxel at
#: the border must be wholly outside, or the coarse surface is open)
MAX_FACTOR = 6


def mni_tissue_path(tissue: str):
    """The ICBM 2009a tissue probability map ``tissue`` ('wm', 'gm') shipped with nilearn."""
    return _data_file("nilearn", f"datasets/data/mni_icbm152_{tissue}_tal_nlin_sym_09a_converted.nii.gz",
                      _NILEARN_HINT)


def coarse_grid(shape, origin, spacing, factors) -> tuple[tuple[int, int, int], np.ndarray, np.ndarray]:
    """(shape, origin, spacing) of the grid whose voxels are ``factors`` blocks of the fine grid from voxel 0:
    each coarse voxel centre is the centre of its block (the mean of its fine voxel centres)."""
    k = np.asarray(factors, int)
    spacing = np.broadcast_to(np.asarray(spacing, float), (3,))
    cshape = tuple(int(-(-s // f)) for s, f in zip(shape, k))
    return cshape, np.asarray(origin, float) + 0.5 * (k - 1) * spacing, k * spacing


def block_fraction(mask: np.ndarray, factors) -> np.ndarray:
    """Each ``factors`` block's inside fraction (the fine mask padded with outside voxels at the high end to a
    multiple of the factors): the exact partial volume of the coarse voxel in the fine voxel set."""
    m = np.asarray(mask, bool)
    k = tuple(int(f) for f in factors)
    pad = [(0, (-s) % f) for s, f in zip(m.shape, k)]
    m = np.pad(m, pad)
    nx, ny, nz = (s // f for s, f in zip(m.shape, k))
    blocks = m.reshape(nx, k[0], ny, k[1], nz, k[2])
    return blocks.sum(axis=(1, 3, 5), dtype=np.int64) / float(np.prod(k))


class FineReferencePhantom(MeshPhantom):
    """A fine segmentation whose truth is its own surface and whose inputs are its coarse versions (module
    docstring).

    Parameters
    ----------
    mask : array_like of bool, shape (nx, ny, nz)
        The fine segmentation, with at least :data:`MAX_FACTOR` outside voxels on every face.
    origin, spacing : array_like, shape (3,)
        World position of voxel (0, 0, 0) and the voxel size (world units, mm).
    name, source : str
        For listings and result records.

    Raises
    ------
    InputError
        A mask without inside voxels or with inside voxels within :data:`MAX_FACTOR` of a face.
    """

    truth_note = ("scored against the fine (1 mm) segmentation: the zero level set of its signed distance "
                  "(marching cubes); the input is the segmentation coarsened by whole voxel blocks")
    #: which protocol: the phantom's own grid, not the config's N (bench/run/grid.py)
    native_grid: ClassVar[bool] = True
    shape_kind: ClassVar[str | None] = None

    def __init__(self, mask, origin, spacing, *, name: str | None = None, source: str | None = None,
                 crease_angle_deg: float = 60.0):
        from skimage.measure import marching_cubes

        from .masks import mask_to_sdf

        m = np.asarray(mask, bool)
        if m.ndim != 3 or not m.any():
            raise InputError("a fine segmentation must be a 3-D mask with inside voxels")
        inner = m[MAX_FACTOR:-MAX_FACTOR, MAX_FACTOR:-MAX_FACTOR, MAX_FACTOR:-MAX_FACTOR]
        if inner.sum() != m.sum():
            raise InputError(f"a fine segmentation needs {MAX_FACTOR} outside voxels on every face (its coarse "
                             "versions' border voxels must be wholly outside)")
        self.fine_mask = m
        self.fine_origin = np.asarray(origin, float)
        self.fine_spacing = np.broadcast_to(np.asarray(spacing, float), (3,)).copy()
        sdf = mask_to_sdf(m, self.fine_origin, self.fine_spacing)
        h = float(self.fine_spacing.min())
        v, f, _, _ = marching_cubes(sdf.values - TIE_BREAK * h, 0.0, spacing=tuple(self.fine_spacing),
                                    allow_degenerate=False)
        super().__init__(v + self.fine_origin, f, name=name, normalize=False, crease_angle_deg=crease_angle_deg,
                         curvature_radius=2.0 * h, source=source)
        self.voxel_mm = h

    @property
    def fine_volume(self) -> float:
        """The fine mask's volume: inside voxels × voxel volume."""
        return float(self.fine_mask.sum()) * float(np.prod(self.fine_spacing))

    @property
    def params(self) -> dict:
        p = super().params
        p.update(fine_shape=list(self.fine_mask.shape), fine_origin=self.fine_origin.tolist(),
                 fine_spacing=self.fine_spacing.tolist())
        return p

    def volume(self, n=None, extent=None, variant: str = "sdf") -> Volume:
        """The fine segmentation itself as a mask input (its signed distance, kind ``mask``) on its own grid;
        ``n`` and ``extent`` do not apply."""
        if variant != "sdf":
            raise InputError(f"phantom {self.name!r} is a segmentation: only variant 'sdf' exists (got {variant!r})")
        from .masks import mask_to_sdf

        sdf = mask_to_sdf(self.fine_mask, self.fine_origin, self.fine_spacing)
        return Volume(sdf.values, sdf.origin, sdf.spacing, kind="mask", raw=self.fine_mask.astype(np.float64),
                      level=0.5)

    def native_n(self) -> int:
        """The grid's N for this phantom: the fine grid's largest dimension."""
        return int(max(self.fine_mask.shape))

    def block_factors(self, degradation) -> tuple[int, int, int]:
        """The (x, y, z) block of a degradation: ``downsample@K`` K × K × K, times ``thick_slices@K`` along z."""
        from .degrade import parse_degradation

        d = parse_degradation(degradation)
        k = (d.downsample, d.downsample, d.downsample * d.thick_slices)
        if max(k) > MAX_FACTOR:
            raise InputError(f"degradation {d}: a block of {k[0]} x {k[1]} x {k[2]} fine voxels; at most "
                             f"{MAX_FACTOR} along an axis (the fine mask's outside margin)")
        return k

    def coarse_fraction(self, factors) -> Volume:
        """The exact partial-volume image of the ``factors`` blocks, on the coarse grid (:func:`coarse_grid`)."""
        frac = block_fraction(self.fine_mask, factors)
        _, origin, spacing = coarse_grid(self.fine_mask.shape, self.fine_origin, self.fine_spacing, factors)
        return Volume(frac, origin, spacing)

    def coarse_input(self, degradation, seed: int = 0) -> Volume:
        """The volume a method gets for ``degradation`` (module docstring): a coarse mask or partial-volume image
        with its level set, world units."""
        from .degrade import image_input, parse_degradation

        d = parse_degradation(degradation)
        if d.kind == "sdf":
            raise InputError(f"degradation {d}: the input of a fine segmentation is a coarse mask or partial-volume "
                             "image; add +mask or +partial_volume")
        frac = self.coarse_fraction(self.block_factors(d))
        return image_input(frac.values, d, frac.origin, frac.spacing, seed)


class _MNITissue(FineReferencePhantom):
    """A cropped ICBM 2009a tissue map thresholded at probability 0.5 (module docstring)."""

    tissue: ClassVar[str] = ""
    data = 'nilearn (pip install -e ".[real]")'
    #: the crop: a cube of CROP_MM fine voxels centred at CENTRE_MM (MNI, mm); pieces under MIN_PIECE voxels dropped
    CENTRE_MM: ClassVar[tuple[float, float, float]] = (-30.0, -40.0, 20.0)
    CROP_MM: ClassVar[int] = 60
    MIN_PIECE: ClassVar[int] = 27
    THRESHOLD: ClassVar[float] = 0.5

    def __init__(self, crease_angle_deg: float = 60.0):
        mask, origin, spacing = _mni_crop(mni_tissue_path(self.tissue), self.CENTRE_MM, self.CROP_MM,
                                          self.THRESHOLD, self.MIN_PIECE)
        super().__init__(mask, origin, spacing, crease_angle_deg=crease_angle_deg,
                         source=f"nilearn:datasets/data/mni_icbm152_{self.tissue}_tal_nlin_sym_09a_converted.nii.gz")


def _mni_crop(path, centre_mm, crop: int, threshold: float, min_piece: int):
    """(mask, origin, spacing): the map at ``path`` thresholded, its largest 26-connected component, cropped to
    ``crop`` voxels about ``centre_mm``, pieces under ``min_piece`` voxels dropped, :data:`MAX_FACTOR` outside
    voxels padded on every face."""
    import nibabel as nib
    from scipy import ndimage

    from .io import _origin_spacing_from_affine

    img = nib.as_closest_canonical(nib.load(str(path)))
    raw = np.asarray(img.dataobj)
    prob = raw / 255.0 if np.issubdtype(raw.dtype, np.integer) else np.asarray(raw, float)
    origin, spacing = _origin_spacing_from_affine(img.affine, path)
    joined = np.ones((3, 3, 3), bool)                          # 26-connected, as the truth surface joins them
    lab, n = ndimage.label(prob > threshold, structure=joined)
    if n == 0:
        raise InputError(f"{path}: no voxel above probability {threshold}")
    mask = lab == (np.argmax(np.bincount(lab.ravel())[1:]) + 1)
    lo = np.round((np.asarray(centre_mm) - origin) / spacing).astype(int) - crop // 2
    if (lo < 0).any() or (lo + crop > np.array(mask.shape)).any():
        raise InputError(f"{path}: the crop about {centre_mm} mm leaves the image")
    sub = mask[lo[0]:lo[0] + crop, lo[1]:lo[1] + crop, lo[2]:lo[2] + crop]
    lab, n = ndimage.label(sub, structure=joined)
    sizes = np.bincount(lab.ravel())
    keep = sizes >= min_piece
    keep[0] = False
    sub = keep[lab]
    origin = origin + (lo - MAX_FACTOR) * spacing
    return np.pad(sub, MAX_FACTOR), origin, spacing


class MNIWhiteMatter(_MNITissue):
    name = "mni_wm"
    description = ("ICBM 2009a white matter (nilearn, 1 mm), 60 mm cube of the left parieto-occipital lobe; "
                   "input = its x2 / x3 / thick-slice versions, truth = its own surface")
    tissue = "wm"
    shape_kind = "tubes"        # branching stalks a few voxels thick; its genus (7) is low beside the grey matter's
    genus = 7                   # the instance recomputes it from the truth mesh
    has_creases = True          # marching-cubes terraces of the 1 mm mask


class MNIGreyMatter(_MNITissue):
    name = "mni_gm"
    description = ("ICBM 2009a grey matter (nilearn, 1 mm), the same cube: a folded thin shell with pockets; "
                   "input = its x2 / x3 / thick-slice versions, truth = its own surface")
    tissue = "gm"
    shape_kind = "thin shell"   # with 41 enclosed pockets and genus 125
    genus = 125
    has_creases = True


FINE_SHAPES: dict[str, type[FineReferencePhantom]] = {cls.name: cls for cls in (MNIWhiteMatter, MNIGreyMatter)}


def get_fine_phantom(name: str, **params) -> FineReferencePhantom:
    """A named real-tier phantom, cached per process and parameters."""
    if name not in FINE_SHAPES:
        raise InputError(f"unknown real-tier phantom {name!r}; valid: {', '.join(FINE_SHAPES)}")
    return _cached(("fine", name, tuple(sorted(params.items()))), name, lambda: FINE_SHAPES[name](**params))
