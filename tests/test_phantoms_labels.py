"""phantoms/labels.py: a label map as one phantom per label."""

import nibabel as nib
import numpy as np
import pytest

from phantoms import InputError, expand_phantoms, get_phantom


@pytest.fixture
def label_map(tmp_path):
    lab = np.zeros((30, 30, 30), np.int16)
    lab[3:10, 3:10, 3:10] = 1
    lab[12:20, 5:15, 5:15] = 2
    lab[5:25, 18:27, 18:27] = 5
    path = tmp_path / "organs.nii.gz"
    nib.save(nib.Nifti1Image(lab, np.eye(4)), str(path))
    return path, lab


def test_labels_all_is_one_phantom_per_label_named_by_label(label_map):
    path, lab = label_map
    pairs = expand_phantoms([f"volume:{path}?labels=all"])
    assert [n for n, _ in pairs] == ["organs_label1", "organs_label2", "organs_label5"]
    for (name, source), label in zip(pairs, (1, 2, 5)):
        vol = get_phantom(source).volume()
        assert vol.kind == "mask" and np.array_equal(vol.raw > 0.5, lab == label), name
    assert [n for n, _ in expand_phantoms([f"volume:{path}?labels=5,1"])] == ["organs_label5", "organs_label1"]


def test_bad_label_lists_are_one_line(label_map, tmp_path):
    path, _ = label_map
    ct = tmp_path / "ct.nii.gz"
    nib.save(nib.Nifti1Image(np.random.default_rng(0).random((10, 10, 10)).astype(np.float32), np.eye(4)), str(ct))
    cases = [(f"volume:{path}?labels=3", "label 3 does not occur in the image; labels present: 1, 2, 5"),
             (f"volume:{ct}?labels=all", "labels= needs a label map; the image holds non-integer values"),
             (f"volume:{path}?labels=all&threshold=2", "not labels and threshold"),
             (f"volume:{path}?labels=a,b", "expected all or a comma-separated list of integer labels")]
    for spec, words in cases:
        with pytest.raises(InputError) as err:
            expand_phantoms([spec])
        assert words in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_an_absent_single_label_is_refused_when_the_phantoms_are_expanded(label_map):
    """label=L that the image lacks: refused with the phantom list (before any work), naming the labels present."""
    path, _ = label_map
    with pytest.raises(InputError, match="label 4 does not occur in the image; labels present: 1, 2, 5"):
        expand_phantoms([f"volume:{path}?label=4"])
    assert expand_phantoms([f"volume:{path}?label=5"]) == [(f"volume:{path}?label=5",) * 2]
