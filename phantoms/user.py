"""A user's own volume as a phantom: ``volume:PATH[?key=value&...]`` (docs/PHANTOMS.md, "Your own volumes").

The image is read with its geometry (:mod:`phantoms.images`: NIfTI, NRRD, MetaImage, a DICOM series folder,
``.npz`` / ``.npy``) and turned into a level set in the file's world coordinates (RAS+), nothing rescaled:

* a **mask** (``mask=yes``, or ``auto`` and the image holds two values, e.g. 0/1 or 0/255: the larger is
  inside), a **threshold** (``threshold=T``: values above T are inside) or a **label** (``label=L``: voxels equal
  to L are inside) becomes a signed distance by :func:`phantoms.io.mask_to_sdf` — zero half-way between an inside
  and an outside voxel centre, world units with the real spacing;
* an **intensity at an iso-level** (``level=T``: values above T are inside) becomes φ = T − I, the intensity
  itself as a level set: its sub-voxel boundary is kept (a threshold makes a mask of it first); the volume says
  so (kind ``intensity``, raw = the image, level = T) and its fidelity metrics are read on φ / |∇φ|;
* otherwise the values are the level set φ as given (negative inside).

``invert=yes`` swaps inside and outside; ``pad=K`` adds K outside voxels on every face (a mask that touches the
image border has an open zero level set and is refused without it).

Options
    ``mask`` auto | yes | no; ``threshold`` number; ``label`` integer; ``level`` number; ``invert`` yes | no; ``pad``
    integer ≥ 0; ``truth`` a closed mesh file in the same world coordinates (every truth metric is computed against it)
    or a label image (its voxels > 0, or equal to ``label`` when given, are the reference segmentation; its surface is
    the zero level set of that mask's signed distance, extracted by marching cubes: vertices on the grid edges half-way
    between an inside and an outside voxel centre); ``resample`` no | yes (default no: the native grid — the grid's N is
    then the largest dimension; yes: N points along the longest world axis, isotropic spacing, trilinear); ``series`` a
    DICOM series UID (a folder holding several).

The same options are a TOML table in a config: ``{ volume = "ct.nrrd", threshold = 300 }``.
"""

from __future__ import annotations

import math
import re

import numpy as np

from geometry.errors import InputError

from .base import Phantom
from .images import read_image
from .user_truth import read_truth
from .volume import Volume, check_grid, check_memory

__all__ = ["VOLUME_PREFIX", "VolumePhantom", "parse_spec", "format_spec", "spec_from_table", "level_set_from_image"]

VOLUME_PREFIX = "volume:"
_OPTIONS = ("mask", "threshold", "label", "labels", "level", "invert", "pad", "truth", "resample", "series")
_SPEC = re.compile(r"^(?P<path>.*?)(?:\?(?P<opts>[A-Za-z_]+=.*))?$", re.S)
_YES = {"yes": True, "true": True, "1": True, "on": True, "no": False, "false": False, "0": False, "off": False}


def _bool(key: str, value) -> bool:
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text not in _YES:
        raise InputError(f"volume option {key}={value!r}: expected yes or no")
    return _YES[text]


def _check_options(opts: dict, where: str) -> dict:
    """The options with their types (InputError naming the spec and the bad option)."""
    out: dict = {}
    for key, value in opts.items():
        if key not in _OPTIONS:
            raise InputError(f"{where}: unknown option {key!r}; valid options: {', '.join(_OPTIONS)}")
        try:
            if key == "mask":
                text = str(value).strip().lower() if not isinstance(value, bool) else ("yes" if value else "no")
                text = {"true": "yes", "false": "no", "1": "yes", "0": "no"}.get(text, text)
                if text not in ("auto", "yes", "no"):
                    raise InputError("expected auto, yes or no")
                out[key] = text
            elif key in ("threshold", "level"):
                if isinstance(value, bool):
                    raise InputError("expected a number, not a boolean")
                t = float(value)
                if not math.isfinite(t):
                    raise InputError("expected a finite number")
                out[key] = t
            elif key in ("label", "pad"):
                if isinstance(value, bool):
                    raise InputError("expected an integer, not a boolean")
                if float(value) != int(float(value)):
                    raise InputError("expected an integer")
                out[key] = int(float(value))
                if key == "pad" and out[key] < 0:
                    raise InputError("expected an integer >= 0")
            elif key == "labels":
                out[key] = _labels_option(value)
            elif key in ("invert", "resample"):
                out[key] = _bool(key, value)
            else:
                out[key] = str(value)
        except InputError as exc:
            raise InputError(f"{where}: option {key}={value!r}: {exc}") from None
        except (TypeError, ValueError):
            raise InputError(f"{where}: option {key}={value!r}: expected a number") from None
        except OverflowError:                                      # int(inf), int(float("1e400"))
            raise InputError(f"{where}: option {key}={value!r}: expected a finite number") from None
    given = [k for k in ("label", "labels", "threshold", "level") if k in out]
    if len(given) > 1:
        raise InputError(f"{where}: give one of label=, labels=, threshold= and level=, not {' and '.join(given)}")
    if "level" in out and out.get("mask") == "yes":
        raise InputError(f"{where}: level= reads intensities as a level set; it cannot be combined with mask=yes")
    if out.get("mask") == "no" and ("label" in out or "threshold" in out):
        raise InputError(f"{where}: mask=no reads the values as a level set; it cannot be combined with "
                         "label= or threshold=")
    return out


def parse_spec(spec: str) -> tuple[str, dict]:
    """``volume:PATH?key=value&...`` → ``(PATH, options)`` (options typed and checked)."""
    if not spec.startswith(VOLUME_PREFIX):
        raise InputError(f"not a volume phantom: {spec!r} (expected {VOLUME_PREFIX}PATH)")
    m = _SPEC.match(spec[len(VOLUME_PREFIX):])
    path, text = m.group("path"), m.group("opts") or ""
    if not path:
        raise InputError(f"{spec!r}: no file given (expected {VOLUME_PREFIX}PATH[?key=value&...])")
    opts: dict = {}
    for item in filter(None, text.split("&")):
        key, eq, value = item.partition("=")
        if not eq:
            raise InputError(f"{spec!r}: option {item!r} is not key=value")
        if key.strip() in opts:                 # the second value used to win silently
            raise InputError(f"{spec!r}: option {key.strip()!r} is given twice")
        opts[key.strip()] = value.strip()
    return path, _check_options(opts, spec)


def _labels_option(value) -> str:
    """``labels=all`` or a comma list of integer labels, as canonical text."""
    text = str(value).strip().lower()
    if text == "all":
        return text
    try:
        labels = [float(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise InputError("expected all or a comma-separated list of integer labels") from None
    if not labels or not all(math.isfinite(x) and x == int(x) for x in labels):
        raise InputError("expected all or a comma-separated list of integer labels")
    return ",".join(str(int(x)) for x in dict.fromkeys(labels))


def format_spec(path: str, options: dict) -> str:
    """The canonical spec string of ``path`` and ``options`` (sorted keys; what names the phantom)."""
    def text(v):
        return ("yes" if v else "no") if isinstance(v, bool) else (f"{v:g}" if isinstance(v, float) else str(v))

    query = "&".join(f"{k}={text(options[k])}" for k in sorted(options))
    return f"{VOLUME_PREFIX}{path}" + (f"?{query}" if query else "")


def spec_from_table(table: dict, where: str) -> str:
    """A config's phantom table — ``{volume = "PATH", key = value, ...}`` or ``{mesh = "PATH"}`` — as a spec string."""
    if "mesh" in table:
        if len(table) != 1 or not isinstance(table["mesh"], str):
            raise InputError(f"{where}: a mesh phantom table is {{ mesh = \"PATH\" }} (no options)")
        return f"mesh:{table['mesh']}"
    if not isinstance(table.get("volume"), str):
        raise InputError(f"{where}: a phantom table needs volume = \"PATH\" (or mesh = \"PATH\")")
    opts = {k: v for k, v in table.items() if k != "volume"}
    return format_spec(table["volume"], _check_options(opts, where))


# ---------------------------------------------------------------------------------------------- level set
def _two_values(values: np.ndarray) -> tuple[float, float] | None:
    """(low, high) when the image holds exactly two distinct values, else None (one pass, no sort)."""
    lo, hi = values.min(), values.max()
    if lo == hi:
        return None
    return (float(lo), float(hi)) if bool(((values == lo) | (values == hi)).all()) else None


def _label_list(values: np.ndarray) -> str:
    labels = np.unique(values)
    shown = ", ".join(f"{x:g}" for x in labels[:20].astype(float))
    return shown + (f", … ({len(labels)} in all)" if len(labels) > 20 else "")


def _inside(values: np.ndarray, opts: dict, where: str) -> np.ndarray | None:
    """The inside voxels (bool) for a mask / threshold / label reading, None when the values are φ."""
    mode = opts.get("mask", "auto")
    if "label" in opts:
        if not (np.issubdtype(values.dtype, np.integer) or values.dtype == bool
                or bool(np.all(np.mod(values, 1) == 0))):
            raise InputError(f"{where}: label={opts['label']} needs an integer label image; the values are not "
                             "integers (use threshold= for an intensity image)")
        inside = values == opts["label"]
        if not inside.any():
            raise InputError(f"{where}: label {opts['label']} does not occur in the image; labels present: "
                             f"{_label_list(values)}")
    elif "threshold" in opts:
        inside = values > opts["threshold"]
        if not inside.any() or inside.all():
            none = 'no voxel' if not inside.any() else 'every voxel'
            raise InputError(f"{where}: threshold {opts['threshold']:g} leaves {none} "
                             f"inside (values range over [{float(values.min()):g}, {float(values.max()):g}]); "
                             "values above the threshold are inside")
    elif mode == "no":
        return None
    else:
        pair = _two_values(values) if values.dtype != bool else (0.0, 1.0)
        if pair is None and values.min() == values.max() and float(values.min()) in (0.0, 1.0):
            pair = (0.0, 1.0)                   # a constant 0/1 array is an empty or a full mask
        if pair is None:
            if mode == "yes":
                raise InputError(f"{where}: mask=yes but the image holds more than two values (range "
                                 f"[{float(values.min()):g}, {float(values.max()):g}]); give threshold=T "
                                 "(values above T are inside) or label=L")
            return None
        inside = values == pair[1] if values.dtype != bool else values.copy()
    if opts.get("invert"):
        inside = ~inside
    if not inside.any() or inside.all():
        raise InputError(f"{where}: the mask has {'no inside' if not inside.any() else 'no outside'} voxels: "
                         "there is no surface to reconstruct")
    return inside


def _border_faces(inside: np.ndarray) -> list[str]:
    faces = []
    for axis, name in enumerate("xyz"):
        for side, tag in ((0, "−"), (-1, "+")):
            if np.take(inside, side, axis=axis).any():
                faces.append(f"{name}{tag}")
    return faces


def _intensity_level_set(image, opts: dict, where: str, require_surface: bool) -> Volume:
    """``level=T``: φ = T − I (inside above T; ``invert``: below), kind ``intensity`` with raw I and level T."""
    values = np.asarray(image.values, np.float64)
    lo, hi = float(values.min()), float(values.max())
    level = float(opts["level"])
    if not lo < level < hi:
        raise InputError(f"{where}: level={level:g} is outside the image's values (range [{lo:g}, {hi:g}]): "
                         "nothing would be inside or outside")
    if "pad" in opts:
        raise InputError(f"{where}: pad= adds outside voxels to a mask; with level= the intensity is the level set")
    raw, lev = (-values, -level) if opts.get("invert") else (values, level)
    vol = Volume(lev - raw, image.origin, image.spacing, kind="intensity", raw=raw, level=lev)
    if require_surface and not vol.is_closed():
        raise InputError(f"{where}: at level={level:g} the inside reaches the image border: the surface is open; "
                         "crop or extend the volume")
    return vol


def level_set_from_image(image, opts: dict, where: str, require_surface: bool = True) -> Volume:
    """The level-set :class:`Volume` of an :class:`phantoms.images.Image` under the spec's options.

    ``require_surface`` (a phantom): φ read as given must have a closed zero level set inside the grid."""
    values = image.values
    try:
        check_grid(image.origin, image.spacing, values.shape)       # origin / spacing checked before any work
        if values.dtype.kind == "f" and not np.isfinite(values).all():
            Volume(values, image.origin, image.spacing)             # names the NaN / inf
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    if "level" in opts:
        return _intensity_level_set(image, opts, where, require_surface)
    inside = _inside(values, opts, where)
    origin, spacing = np.asarray(image.origin, float), np.asarray(image.spacing, float)
    pad = int(opts.get("pad", 0))
    if inside is None and "pad" in opts:
        raise InputError(f"{where}: pad= adds outside voxels to a mask, but the values are read as a level set "
                         "(mask=no, or more than two values without threshold= / label=)")
    if inside is None:
        phi = -values.astype(np.float64) if opts.get("invert") else values.astype(np.float64)
        if not require_surface:
            try:
                return Volume(phi, origin, spacing)
            except InputError as exc:
                raise InputError(f"{where}: {exc}") from None
        if not (phi.min() < 0 < phi.max()):
            raise InputError(f"{where}: the values have no zero level set (range [{phi.min():g}, {phi.max():g}]); "
                             "for an intensity image or a mask give threshold=T (values above T are inside) or "
                             "label=L, or mask=yes")
        vol = Volume(phi, origin, spacing)
        if not vol.is_closed():
            raise InputError(f"{where}: the zero level set reaches the image border (φ ≤ 0 on a boundary face): the "
                             "surface is open; crop or extend the volume so that φ > 0 on its border")
        return vol
    if pad:
        check_memory(tuple(s + 2 * pad for s in inside.shape), 6, what=f"{where} padded by {pad}")
        inside = np.pad(inside, pad, constant_values=False)
        origin = origin - pad * np.broadcast_to(spacing, (3,))
    border = _border_faces(inside)
    if border:
        raise InputError(f"{where}: the mask touches the image border (faces {', '.join(border)}), so its zero "
                         "level set is open; add pad=1 (one outside voxel on every face)")
    check_memory(inside.shape, 6, what=f"the signed distance of {where}")
    return mask_level_set(inside, origin, spacing)


def mask_level_set(inside: np.ndarray, origin, spacing) -> Volume:
    """The level set of a mask read from an image (``inside`` after any ``pad=``): its signed distance, kind
    ``mask``, the mask as ``raw`` at level ½ — a run's volume cache rebuilds it from the stored mask alone."""
    from .masks import mask_to_sdf

    sdf = mask_to_sdf(inside, origin, spacing)
    return Volume(sdf.values, sdf.origin, sdf.spacing, kind="mask", raw=inside.astype(np.float64), level=0.5)


def check_truth_frame(source: str) -> None:
    """Refuse, before any cell, a ``volume:`` phantom whose ``truth=`` does not fit its volume (voxel-index or LPS
    coordinates, an offset, an intensity image, an open mesh): the volume and its truth are read here once.  A
    volume that cannot be read itself is left to its cells (a failed row each, as without truth)."""
    if not source.startswith(VOLUME_PREFIX):
        return
    path, options = parse_spec(source)
    if options.get("truth") is None:
        return
    try:
        level_set = level_set_from_image(read_image(path, series=options.get("series")), options, path)
    except InputError:
        return
    read_truth(options, level_set, path)


class VolumePhantom(Phantom):
    """A user's volume file as a phantom (see the module docstring); ``truth_phantom`` is None without truth.

    Parameters
    ----------
    spec : str
        ``volume:PATH[?key=value&...]``.
    name : str, optional
        The phantom's name in results (default: ``spec``).
    level_set : Volume, optional
        The level set this spec's image gives, when it is known (a run's volume cache): the image is not read.

    Raises
    ------
    InputError
        An unreadable image, bad options, or a ``truth=`` file that is missing or does not fit the volume.
    """

    description = "a user's volume file"
    paper_snr_db = None

    def __init__(self, spec: str, name: str | None = None, level_set: Volume | None = None):
        self.spec = spec
        self.name = name or spec
        self.path, self.options = parse_spec(spec)
        if level_set is None:       # given: the one this spec's image gives, kept by a run's volume cache
            image = read_image(self.path, series=self.options.get("series"))
            level_set = level_set_from_image(image, self.options, self.path)
        self.level_set = level_set
        self.truth_phantom = None
        if self.options.get("truth") is not None:
            self.truth_phantom = read_truth(self.options, self.level_set, self.path)
            self.genus = self.truth_phantom.genus
            self.n_components = self.truth_phantom.n_components
            self.has_creases = self.truth_phantom.has_creases
            self.truth_note = self.truth_phantom.truth_note
        else:
            self.truth_note = "no ground truth: data fidelity and mesh quality only"

    @property
    def has_truth(self) -> bool:
        return self.truth_phantom is not None

    @property
    def params(self) -> dict:
        v = self.level_set
        return {"source": self.path, "shape": list(v.shape), "origin": v.origin.tolist(),
                "spacing": v.spacing.tolist(), **self.options}

    def ground_truth(self):
        return self.truth_phantom

    def native_n(self) -> int:
        """The grid's N for this phantom on its native grid: its largest dimension."""
        return int(max(self.level_set.shape))

    def volume(self, n: int | None = None, extent: float | None = None, variant: str = "sdf") -> Volume:
        """The level set on its native grid (``n`` None or 0, or ``resample`` off), or resampled to ``n`` points
        along the longest world axis (isotropic spacing, trilinear) with ``resample=yes``; ``extent`` is unused
        (the grid is the file's)."""
        if variant != "sdf":
            raise InputError(f"phantom {self.name!r} is a user volume: only variant 'sdf' exists (got {variant!r})")
        native = self.level_set
        if not n or not self.options.get("resample") or int(n) == self.native_n():
            return native.with_values(native.values.copy())
        n = int(n)
        if n < 8:
            raise InputError(f"grid size N must be an integer >= 8; got {n}")
        span = native.upper - native.lower
        h = float(span.max()) / (n - 1)
        shape = tuple(int(math.floor(s / h + 1e-9)) + 1 for s in span)
        check_memory(shape, 8, what=f"{self.name} resampled to N = {n}")
        axes = [native.origin[d] + h * np.arange(shape[d]) for d in range(3)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        return Volume(native(pts, clamp=True).reshape(shape), native.origin, h)

    # truth queries: the reference surface's, when there is one
    def _truth(self):
        if self.truth_phantom is None:
            raise InputError(f"phantom {self.name!r} has no ground truth (give truth=MESH or truth=LABELS)")
        return self.truth_phantom

    def sdf(self, points):
        return self._truth().sdf(points)

    def paper(self, points):
        raise InputError(f"phantom {self.name!r} is a user volume: it has no 'paper' polynomial")

    def truth(self, points):
        return self._truth().truth(points)

    def sample_surface(self, n: int, seed: int = 0):
        return self._truth().sample_surface(n, seed)

    def __repr__(self) -> str:
        return f"VolumePhantom({self.spec!r})"

