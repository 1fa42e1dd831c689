"""Seeded additive noise at a requested signal-to-noise ratio (docs/PHANTOMS.md, "Noise").

SNR_dB = 10·log10(mean(φ²) / σ²), the mean over the whole grid.  Gaussian noise has standard deviation σ;
uniform noise is drawn on [−a, a] with a = σ√3 (the same variance).  The generator is NumPy's PCG64 seeded
with ``seed``, so the same seed gives a bitwise-identical volume on every machine.
"""

from __future__ import annotations

import math

import numpy as np

from geometry.errors import InputError
from .volume import Volume

NOISE_KINDS = ("none", "gaussian", "uniform")

__all__ = ["NOISE_KINDS", "add_noise", "snr_db"]


def snr_db(signal: np.ndarray, noise: np.ndarray) -> float:
    """The signal-to-noise ratio 10·log10(mean(signal²) / mean(noise²)) in dB.

    Parameters
    ----------
    signal, noise : numpy.ndarray
        The clean field and the additive noise (any shape; means over all entries).

    Returns
    -------
    float
        The SNR in dB; inf for zero noise.
    """
    p_noise = float(np.mean(np.square(noise)))
    if p_noise == 0.0:
        return math.inf
    return 10.0 * math.log10(float(np.mean(np.square(signal))) / p_noise)


def add_noise(volume: Volume, kind: str = "gaussian", snr: float | None = None,
              seed: int = 0) -> tuple[Volume, float]:
    """Add seeded noise to a volume at a requested SNR.

    Parameters
    ----------
    volume : Volume
        The clean volume.
    kind : {'none', 'gaussian', 'uniform'}
        The noise distribution (:data:`NOISE_KINDS`); ``'none'`` returns a copy of the volume unchanged.
    snr : float, optional
        The requested SNR in dB; required unless ``kind`` is ``'none'``.
    seed : int
        Seed (>= 0) of the PCG64 generator: the same seed gives a bitwise-identical volume on every machine.

    Returns
    -------
    noisy : Volume
        The volume plus the noise.
    achieved_snr_db : float
        The SNR measured on the noise actually drawn (inf for ``'none'``).

    Raises
    ------
    InputError
        An unknown kind, a negative or non-integer seed, a missing or non-finite SNR, or a volume that is zero
        everywhere (no SNR can be set).
    """
    if kind not in NOISE_KINDS:
        raise InputError(f"unknown noise kind {kind!r}; valid kinds: {', '.join(NOISE_KINDS)}")
    try:
        seed = int(seed)
    except (TypeError, ValueError):
        raise InputError(f"seed must be an integer; got {seed!r}") from None
    if seed < 0:
        raise InputError(f"seed must be >= 0 (NumPy's generators take no negative seed); got {seed}")
    if kind == "none":
        return volume.with_values(volume.values.copy()), math.inf
    try:
        snr = float(snr)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise InputError(f"SNR must be a number in dB; got {snr!r}") from None
    if not math.isfinite(snr):
        raise InputError(f"SNR must be finite; got {snr}")
    phi = volume.values
    power = float(np.mean(np.square(phi)))
    if power == 0.0:
        raise InputError("cannot set an SNR for a volume that is zero everywhere")
    sigma = math.sqrt(power / 10.0 ** (snr / 10.0))
    rng = np.random.Generator(np.random.PCG64(seed))
    if kind == "gaussian":
        eta = sigma * rng.standard_normal(phi.shape)
    else:
        a = sigma * math.sqrt(3.0)
        eta = rng.uniform(-a, a, phi.shape)
    return volume.with_values(phi + eta), snr_db(phi, eta)
