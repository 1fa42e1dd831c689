"""phantoms/real.py: the named real shapes (bunny, cortex, brain_mri) load from installed packages."""

import importlib.util

import numpy as np
import pytest

from phantoms import InputError, get_phantom

HAS_NILEARN = importlib.util.find_spec("nilearn") is not None


@pytest.mark.skipif(HAS_NILEARN, reason="nilearn installed")
def test_missing_nilearn_says_what_to_install():
    with pytest.raises(InputError, match=r'pip install -e "\.\[real\]"'):
        get_phantom("cortex")


@pytest.mark.skipif(not HAS_NILEARN, reason='needs nilearn: pip install -e ".[real]"')
def test_cortex_loads():
    ph = get_phantom("cortex")
    assert len(ph.vertices) == 10242 and ph.genus == 0 and ph.n_components == 1
    vol = ph.volume(n=32)
    assert vol.is_closed()
    x, n = ph.sample_surface(300, seed=0)
    assert np.all(ph.sdf(x + 1e-4 * n) > 0) and np.all(ph.sdf(x - 1e-4 * n) < 0)
    t = ph.truth(x)
    assert np.isfinite(t.H).mean() > 0.8


@pytest.mark.skipif(not HAS_NILEARN, reason='needs nilearn: pip install -e ".[real]"')
def test_brain_mri_loads():
    ph = get_phantom("brain_mri")
    assert "marching-cubes" in ph.truth_note and ph.genus == 0
    vol = ph.volume(n=32)
    assert vol.is_closed()
    # the resampled MRI distance vanishes on the truth surface (to within a voxel) and has the right sign
    x, n = ph.sample_surface(2000, seed=1)
    vox = ph.voxel_mm * ph.scale
    assert np.abs(ph.mri_sdf(x)).max() < vox
    assert np.all(ph.mri_sdf(x + 2 * vox * n) > 0) and np.all(ph.mri_sdf(x - 2 * vox * n) < 0)
    t = ph.truth(x[:300] + 0.01 * n[:300])
    assert np.all(t.signed > 0) and np.all(t.signed <= 0.01 + 1e-12)
    with pytest.raises(InputError, match="only variant 'sdf'"):
        ph.volume(n=16, variant="paper")


def test_cli_volume_for_a_real_shape(tmp_path):
    from bench.cli import main

    out = tmp_path / "b.npz"
    assert main(["volume", "bunny", "--n", "24", "--noise", "gaussian", "--snr", "40", "-o", str(out)]) == 0
    assert out.exists()
