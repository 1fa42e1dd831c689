"""phantoms/registry.py: phantom names, mesh:PATH, get_phantom's errors."""

import numpy as np
import pytest
import trimesh

from phantoms import PHANTOMS, InputError, MeshPhantom, get_phantom, grid_volume, is_phantom_name, phantom_names


def _icosphere(subdivisions=3, radius=1.5):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices), np.asarray(m.faces)


def test_bad_phantom_inputs():
    with pytest.raises(InputError, match="valid phantoms: sphere"):
        get_phantom("blob")
    with pytest.raises(InputError, match="N must be an integer >= 8"):
        get_phantom("sphere").volume(n=7)
    with pytest.raises(InputError, match="variant"):
        get_phantom("sphere").volume(n=8, variant="exact")
    with pytest.raises(InputError, match="shape"):
        get_phantom("sphere").truth(np.zeros((3, 2)))
    with pytest.raises(InputError, match="extent"):
        grid_volume(lambda p: p[:, 0], 8, extent=-1)


def test_mesh_prefix_and_registry(tmp_path):
    v, f = _icosphere(2, 3.0)
    path = tmp_path / "ball.ply"
    trimesh.Trimesh(v, f).export(path)
    ph = get_phantom(f"mesh:{path}")
    assert isinstance(ph, MeshPhantom) and ph.name == f"mesh:{path}" and ph.genus == 0
    assert get_phantom(f"mesh:{path}") is ph                       # cached per process
    assert ph.volume(n=16).is_closed()
    assert list(PHANTOMS) == ["sphere", "ellipsoid", "fused_spheres", "cylinder", "torus"]
    assert phantom_names()[-5:] == ["bunny", "cortex", "brain_mri", "mni_wm", "mni_gm"]
    assert is_phantom_name("bunny") and is_phantom_name(f"mesh:{path}") and not is_phantom_name("blob")
    with pytest.raises(InputError, match="valid phantoms: sphere.*brain_mri, mni_wm, mni_gm, or mesh:PATH"):
        get_phantom("blob")


def test_labels_all_on_an_image_without_a_label_is_refused(tmp_path):
    import nibabel as nib

    from phantoms import expand_phantoms

    nib.save(nib.Nifti1Image(np.zeros((10, 10, 10), np.uint8), np.eye(4)), str(tmp_path / "empty.nii.gz"))
    with pytest.raises(InputError) as err:
        expand_phantoms([f"volume:{tmp_path / 'empty.nii.gz'}?labels=all"])
    assert "holds no label" in str(err.value) and "\n" not in str(err.value)
