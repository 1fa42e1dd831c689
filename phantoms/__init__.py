"""Level-set volumes and their exact ground truth.

>>> from phantoms import get_phantom, add_noise
>>> ph = get_phantom("ellipsoid")
>>> vol = ph.volume(n=64)                      # exact signed distance on a 64³ grid over [-2.5, 2.5]³
>>> noisy, snr = add_noise(vol, "gaussian", 42.0, seed=0)
>>> truth = ph.truth(noisy.grid_points().reshape(-1, 3)[:10])

Modules: ``volume`` (the grid type) < ``base`` (the phantom interface) < ``analytic``, ``mesh/``, ``anatomy/``,
``real``, ``user`` (the phantoms; ``user`` reads a user's image through ``images``) < ``registry`` (names →
phantoms);
``noise`` and ``io`` work on volumes.
"""

from geometry.errors import InputError

from .base import VARIANTS, Phantom, Truth, grid_volume
from .io import check_volume_output, load_volume, mask_to_sdf, save_volume
from .mesh import MeshPhantom
from .noise import NOISE_KINDS, add_noise, snr_db
from .registry import (PHANTOMS, REAL_PHANTOMS, VOLUME_PREFIX, expand_phantoms, get_phantom, is_file_phantom,
                       is_phantom_name, phantom_names, phantom_path, short_name)
from .user import VolumePhantom
from .volume import Sample, Volume

__all__ = [
    "InputError", "Volume", "Sample", "Phantom", "Truth", "PHANTOMS", "VARIANTS", "NOISE_KINDS",
    "get_phantom", "phantom_names", "grid_volume", "add_noise", "snr_db",
    "load_volume", "save_volume", "check_volume_output", "mask_to_sdf", "REAL_PHANTOMS", "is_phantom_name",
    "MeshPhantom", "VolumePhantom", "VOLUME_PREFIX", "expand_phantoms", "is_file_phantom", "phantom_path",
    "short_name",
]
