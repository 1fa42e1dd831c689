"""Level-set volumes and their exact ground truth.

>>> from phantoms import get_phantom, add_noise
>>> ph = get_phantom("ellipsoid")
>>> vol = ph.volume(n=64)                      # exact signed distance on a 64³ grid over [-2.5, 2.5]³
>>> noisy, snr = add_noise(vol, "gaussian", 42.0, seed=0)
>>> truth = ph.truth(noisy.grid_points().reshape(-1, 3)[:10])
"""

from geometry.errors import InputError
from .io import load_volume, mask_to_sdf, save_volume
from .noise import NOISE_KINDS, add_noise, snr_db
from .shapes import (PHANTOMS, REAL_PHANTOMS, VARIANTS, Phantom, Truth, get_phantom, grid_volume, is_phantom_name,
                     phantom_names)
from .volume import Sample, Volume
from .mesh_phantom import MeshPhantom  # noqa: E402  (after .shapes: it subclasses Phantom)

__all__ = [
    "InputError", "Volume", "Sample", "Phantom", "Truth", "PHANTOMS", "VARIANTS", "NOISE_KINDS",
    "get_phantom", "phantom_names", "grid_volume", "add_noise", "snr_db",
    "load_volume", "save_volume", "mask_to_sdf", "REAL_PHANTOMS", "is_phantom_name", "MeshPhantom",
]

