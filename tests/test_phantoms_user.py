"""phantoms/user.py and phantoms/masks.py: a user's volume as a phantom — masks to signed distances, options,
ground truth, globs — with one-line refusals of bad input."""

from __future__ import annotations

import nibabel as nib
import numpy as np
import pytest
import trimesh

from _volumes import BOX_ORIGIN, BOX_SPACING, boxes_mask, sphere_mask, voxel_surface, write_boxes
from phantoms import InputError, expand_phantoms, get_phantom, load_volume, mask_to_sdf
from phantoms.user import format_spec, parse_spec, spec_from_table


def _nifti(path, values, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    aff = np.diag([*spacing, 1.0])
    aff[:3, 3] = origin
    nib.save(nib.Nifti1Image(values, aff), str(path))
    return path


def test_a_0_255_mask_is_a_mask_and_threshold_label_invert_read_intensities(tmp_path):
    m = sphere_mask()
    p = _nifti(tmp_path / "m.nii.gz", (m * 255).astype(np.uint8))
    ref = mask_to_sdf(m)
    assert np.array_equal(load_volume(p).values, ref.values)
    assert np.array_equal(get_phantom(f"volume:{p}").volume().values, ref.values)
    intensity = np.where(m, 300.0, 20.0) + np.random.default_rng(0).normal(0, 5, m.shape)
    q = _nifti(tmp_path / "ct.nii.gz", intensity.astype(np.float32))
    assert np.array_equal(get_phantom(f"volume:{q}?threshold=150").volume().values, ref.values)
    labels = np.where(m, 3, 0).astype(np.int16)
    labels[:4] = 7
    r = _nifti(tmp_path / "lab.nii.gz", labels)
    assert np.array_equal(get_phantom(f"volume:{r}?label=3").volume().values, ref.values)
    inv = get_phantom(f"volume:{q}?threshold=150&invert=yes&pad=1").volume()
    assert (inv.values[1:-1, 1:-1, 1:-1][m] > 0).all() and np.allclose(inv.origin, [-1, -1, -1])


def test_bad_options_and_values_are_one_line(tmp_path):
    m = sphere_mask()
    ramp = np.linspace(0, 1, m.size).reshape(m.shape)             # an intensity image: many values, all > 0
    q = _nifti(tmp_path / "ct.nii.gz", (np.where(m, 300.0, 20.0) + ramp).astype(np.float32))
    lab = _nifti(tmp_path / "lab.nii.gz", np.where(m, 3, 0).astype(np.int16))
    cases = [
        (f"volume:{lab}?label=5", "label 5 does not occur in the image; labels present: 0, 3"),
        (f"volume:{q}?threshold=1000", "threshold 1000 leaves no voxel inside"),
        (f"volume:{q}?threshold=0", "threshold 0 leaves every voxel inside"),
        (f"volume:{q}", "the values have no zero level set"),
        (f"volume:{q}?colour=red", "unknown option 'colour'"),
        (f"volume:{q}?pad=-1", "option pad='-1': expected an integer >= 0"),
        (f"volume:{q}?threshold=abc", "option threshold='abc': expected a number"),
        (f"volume:{q}?label=1&threshold=2",
         "give one of label=, labels=, threshold= and level=, not label and threshold"),
        (f"volume:{q}?mask=yes", "mask=yes but the image holds more than two values"),
        (f"volume:{q}?threshold=100&truth={tmp_path / 'none.obj'}", "no such truth file"),
        (f"volume:{tmp_path / 'missing.nii.gz'}", "no such file"),
        (f"volume:{q}?mask=no&pad=2", "pad= adds outside voxels to a mask, but the values are read as a level set"),
        (f"volume:{q}?level=150&threshold=100",
         "give one of label=, labels=, threshold= and level=, not threshold and level"),
        (f"volume:{q}?level=5000", "level=5000 is outside the image's values (range [20, 300.775])"),
        (f"volume:{q}?level=150&mask=yes", "cannot be combined with mask=yes"),
    ]
    for spec, message in cases:
        with pytest.raises(InputError) as err:
            get_phantom(spec)
        assert message in str(err.value) and "\n" not in str(err.value), (spec, str(err.value))


def test_a_mask_touching_the_border_is_refused_and_pad_closes_it(tmp_path):
    m = sphere_mask()
    m[:, :, :3] = True
    p = _nifti(tmp_path / "open.nii.gz", m.astype(np.uint8), spacing=(0.5, 0.5, 0.8), origin=(1, 2, 3))
    with pytest.raises(InputError, match=r"open.nii.gz: the mask touches the image border \(faces .*z−\).*pad=1"):
        get_phantom(f"volume:{p}")
    vol = get_phantom(f"volume:{p}?pad=2").volume()
    assert vol.shape == tuple(s + 4 for s in m.shape) and vol.is_closed()
    assert np.allclose(vol.origin, [0.0, 1.0, 1.4])


def test_boxes_in_world_coordinates_with_exact_truth_mesh_and_labels(tmp_path):
    nii, obj = write_boxes(tmp_path)
    ph = get_phantom(f"volume:{nii}")
    assert not ph.has_truth and ph.ground_truth() is None
    vol = ph.volume()
    assert np.allclose(vol.origin, BOX_ORIGIN) and np.allclose(vol.spacing, BOX_SPACING)
    with pytest.raises(InputError, match="has no ground truth"):
        ph.truth(np.zeros((1, 3)))
    withmesh = get_phantom(f"volume:{nii}?truth={obj}").ground_truth()
    v, _ = voxel_surface(boxes_mask(), BOX_ORIGIN, BOX_SPACING)
    assert np.allclose(withmesh.vertices.min(0), v.min(0)) and np.allclose(withmesh.scale, 1.0)
    # a label image as truth: the zero level of its mask's distance — on the voxel faces exactly the exact
    # mesh; at edges of an anisotropic grid within (s_max − s_min) / 2 of it (docs/PHANTOMS.md)
    fromlabels = get_phantom(f"volume:{nii}?truth={nii}").ground_truth()
    d = np.abs(withmesh.sdf(fromlabels.vertices))
    assert np.median(d) < 1e-9 and d.max() <= (BOX_SPACING.max() - BOX_SPACING.min()) / 2 + 1e-6


def test_truth_that_is_open_or_elsewhere_is_refused(tmp_path):
    nii, obj = write_boxes(tmp_path)
    box = trimesh.creation.box(extents=(2, 2, 2))
    open_box = trimesh.Trimesh(box.vertices, box.faces[:-1], process=False)
    open_box.export(str(tmp_path / "open.obj"))
    with pytest.raises(InputError, match="truth mesh: .*not watertight"):
        get_phantom(f"volume:{nii}?truth={tmp_path / 'open.obj'}")
    overlap = trimesh.util.concatenate([box, box.copy().apply_translation((1, 0, 0))])   # closed, crosses itself:
    overlap.export(str(tmp_path / "overlap.obj"))                   # resolved to its solid, then checked where it is
    with pytest.raises(InputError, match="the truth surface overlap.obj lies outside the volume"):
        get_phantom(f"volume:{nii}?truth={tmp_path / 'overlap.obj'}")
    box.export(str(tmp_path / "far.obj"))                    # centred on 0: the boxes are at x = 14 ... 25
    with pytest.raises(InputError, match="the truth surface far.obj lies outside the volume"):   # named: a dataset
        get_phantom(f"volume:{nii}?truth={tmp_path / 'far.obj'}")                           # has many truths


def test_a_truth_that_crosses_itself_is_resolved_and_says_so(tmp_path):
    """A truth given as the boxes' surface plus the same surface shifted by a third of a voxel (two overlapping
    copies, as an export of overlapping parts is): resolved to the union's boundary, which lies within a voxel of
    the volume's zero level set and so is accepted; the truth note and the field route say what changed."""
    nii, obj = write_boxes(tmp_path)
    m = trimesh.load(str(obj), process=False)
    shifted = m.copy().apply_translation(BOX_SPACING * [0.31, 0.23, 0.17])
    trimesh.util.concatenate([m, shifted]).export(str(tmp_path / "twice.obj"))
    ph = get_phantom(f"volume:{nii}?truth={tmp_path / 'twice.obj'}")
    truth = ph.ground_truth()
    assert truth.resolution is not None and truth.resolution.crossing_faces > 0
    assert "winding-number ≥ ½ solid" in truth.truth_note
    assert truth.solid_volume > m.volume and truth.resolution.volume_change < 0
    field = get_phantom(f"field:mesh:{tmp_path / 'twice.obj'}")
    assert field.resolution == get_phantom(f"mesh:{tmp_path / 'twice.obj'}").resolution
    assert "winding-number ≥ ½ solid" in field.truth_note


def test_resample_gives_the_grid_n_along_the_longest_axis(tmp_path):
    nii, _ = write_boxes(tmp_path)
    ph = get_phantom(f"volume:{nii}?resample=yes")
    native = ph.volume()
    assert native.shape == boxes_mask().shape and ph.native_n() == 30
    vol = ph.volume(n=40)
    span = native.upper - native.lower
    assert max(vol.shape) == 40 and np.allclose(vol.spacing, span.max() / 39)
    assert np.allclose(vol.origin, native.origin)
    assert get_phantom(f"volume:{nii}").volume(n=40).shape == native.shape     # no resample: native


def test_spec_parsing_and_tables():
    assert parse_spec("volume:ct.nrrd?threshold=300&invert=yes") == ("ct.nrrd", {"threshold": 300.0, "invert": True})
    assert parse_spec("volume:scan?.nii") == ("scan?.nii", {})                   # a glob's ? is not an option
    assert format_spec("ct.nrrd", {"threshold": 300.0, "invert": True}) == "volume:ct.nrrd?invert=yes&threshold=300"
    assert spec_from_table({"volume": "ct.nrrd", "threshold": 300}, "t") == "volume:ct.nrrd?threshold=300"
    assert spec_from_table({"mesh": "a.obj"}, "t") == "mesh:a.obj"
    with pytest.raises(InputError, match="needs volume"):
        spec_from_table({"threshold": 3}, "grid.phantoms[0]")
    with pytest.raises(InputError, match="option 'pad' is given twice"):        # the second used to win silently
        parse_spec("volume:m.nii?pad=2&pad=3")


def test_globs_expand_to_one_phantom_per_file_named_by_stem(tmp_path):
    for name in ("b", "a", "c"):
        trimesh.creation.icosphere(1).export(str(tmp_path / f"{name}.obj"))
    _nifti(tmp_path / "s1.nii.gz", sphere_mask().astype(np.uint8))
    got = expand_phantoms(["sphere", f"mesh:{tmp_path}/*.obj", f"volume:{tmp_path}/*.nii.gz?pad=1"])
    assert got == [("sphere", "sphere"), ("a", f"mesh:{tmp_path}/a.obj"), ("b", f"mesh:{tmp_path}/b.obj"),
                   ("c", f"mesh:{tmp_path}/c.obj"), ("s1", f"volume:{tmp_path}/s1.nii.gz?pad=1")]
    with pytest.raises(InputError, match=r"no file matches the pattern '.*\*.ply'"):
        expand_phantoms([f"mesh:{tmp_path}/*.ply"])
    (tmp_path / "sub").mkdir()
    trimesh.creation.icosphere(1).export(str(tmp_path / "sub" / "a.obj"))
    with pytest.raises(InputError, match="two phantoms are named 'a'"):
        expand_phantoms([f"mesh:{tmp_path}/*.obj", f"mesh:{tmp_path}/sub/*.obj"])


@pytest.mark.parametrize("opts", [{"pad": "inf"}, {"label": "inf"}, {"pad": "1e400"}, {"label": "-inf"}])
def test_a_non_finite_integer_option_is_one_line(opts):
    from phantoms.user import _check_options

    with pytest.raises(InputError, match="expected a finite number"):
        _check_options(opts, "volume:x.nii")


@pytest.mark.parametrize("opts", [{"threshold": True}, {"label": False}, {"pad": True}])
def test_a_boolean_where_a_number_is_expected_is_refused_not_read_as_one(opts):
    from phantoms.user import _check_options

    with pytest.raises(InputError, match="not a boolean"):
        _check_options(opts, "grid.phantoms[0]")


def test_a_users_mask_reaches_the_method_as_a_mask_with_its_voxels(tmp_path):
    m = sphere_mask()
    p = _nifti(tmp_path / "seg.nii.gz", m.astype(np.uint8))
    vol = get_phantom(f"volume:{p}").volume()
    assert vol.kind == "mask" and vol.level == 0.5 and np.array_equal(vol.raw > 0.5, m)
    assert np.array_equal(vol.values < 0, m)                     # φ is the mask's signed distance


def test_a_truth_in_the_wrong_frame_is_refused_naming_the_frame_it_fits(tmp_path):
    m = sphere_mask()
    origin, spacing = np.array([6.0, -31.0, -9.0]), np.array([1.0, 1.0, 1.0])
    nii = _nifti(tmp_path / "seg.nii.gz", m.astype(np.uint8), spacing=tuple(spacing), origin=tuple(origin))
    v, f = voxel_surface(m, origin, spacing)                       # the right truth, in world coordinates
    trimesh.Trimesh(v, f, process=False).export(str(tmp_path / "ok.obj"))
    assert get_phantom(f"volume:{nii}?truth={tmp_path / 'ok.obj'}").has_truth
    cases = {"index.obj": ((v - origin) / spacing, "voxel-index coordinates"),
             "lps.obj": (v * [-1, -1, 1], "LPS coordinates"),
             "shifted.obj": (v + [4.0, 0, 0], "voxels or more from the zero level set (tolerance 2.5)")}
    for name, (w, words) in cases.items():
        trimesh.Trimesh(w, f, process=False).export(str(tmp_path / name))
        with pytest.raises(InputError, match="the truth surface") as err:
            get_phantom(f"volume:{nii}?truth={tmp_path / name}")
        assert words in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_an_intensity_image_as_truth_is_refused(tmp_path):
    m = sphere_mask()
    nii = _nifti(tmp_path / "seg.nii.gz", m.astype(np.uint8))
    ct = _nifti(tmp_path / "ct.nii.gz", (np.where(m, 300.0, 20.0) + np.random.default_rng(0).random(m.shape))
                .astype(np.float32))
    with pytest.raises(InputError, match="non-integer values .*an intensity image, not a label map"):
        get_phantom(f"volume:{nii}?truth={ct}")


def _oblique_nifti(path, degrees: float):
    th = np.radians(degrees)
    aff = np.eye(4)
    aff[:3, :3] = [[np.cos(th), -np.sin(th), 0], [np.sin(th), np.cos(th), 0], [0, 0, 1]]
    nib.save(nib.Nifti1Image(sphere_mask().astype(np.uint8), aff), str(path))
    return path


@pytest.mark.parametrize("degrees", [5, 20, 45, 70])
def test_an_oblique_volume_or_truth_is_refused_with_its_angle_and_info_exits_2(tmp_path, degrees, capsys):
    """The user's phantom and ``info`` read through phantoms/images.py: an oblique grid is never a volume with a
    wrong spacing (issue 40: 45° used to be read at spacing 0.707 × the true one)."""
    from bench.cli import main

    shown = f"{min(degrees, 90 - degrees):g}°"
    obl = _oblique_nifti(tmp_path / "obl.nii.gz", degrees)
    with pytest.raises(InputError, match=rf"obl.nii.gz: the image grid is not axis-aligned .* {shown} .*tolerance"):
        get_phantom(f"volume:{obl}")
    seg = _nifti(tmp_path / "seg.nii.gz", sphere_mask().astype(np.uint8))
    with pytest.raises(InputError, match=rf"obl.nii.gz: the image grid is not axis-aligned .* {shown} "):
        get_phantom(f"volume:{seg}?truth={obl}")
    capsys.readouterr()
    assert main(["info", str(obl)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and shown in err[0], err


def test_a_gapped_dicom_series_as_a_volume_is_refused_naming_the_slice(tmp_path, capsys):
    from _volumes import itk_image, write_dicom_series

    from bench.cli import main

    folder = write_dicom_series(itk_image(sphere_mask().astype(np.int16), (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)),
                                tmp_path / "dcm")
    assert get_phantom(f"volume:{folder}").volume().values.shape == sphere_mask().shape
    (folder / "slice007.dcm").unlink()
    with pytest.raises(InputError, match=r"not evenly spaced: 2 mm between slice 7 \(slice006.dcm"):
        get_phantom(f"volume:{folder}")
    capsys.readouterr()
    assert main(["info", str(folder)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "slice006.dcm" in err[0], err


def test_info_checks_a_truth_too(tmp_path, capsys):
    from bench.cli import main

    m = sphere_mask()
    origin = np.array([6.0, -31.0, -9.0])
    nii = _nifti(tmp_path / "seg.nii.gz", m.astype(np.uint8), origin=tuple(origin))
    v, f = voxel_surface(m, origin, np.ones(3))
    trimesh.Trimesh(v, f, process=False).export(str(tmp_path / "ok.obj"))
    trimesh.Trimesh(v - origin, f, process=False).export(str(tmp_path / "index.obj"))
    assert main(["info", f"volume:{nii}?truth={tmp_path / 'ok.obj'}"]) == 0
    assert "truth:        ground truth = the mesh ok.obj" in capsys.readouterr().out
    assert main(["info", f"volume:{nii}?truth={tmp_path / 'index.obj'}"]) == 2
    err = capsys.readouterr().err
    assert "voxel-index coordinates" in err and err.count("\n") == 1


def test_a_truth_in_the_voxel_indices_of_a_flipped_or_padded_file_is_refused_naming_that_frame(tmp_path):
    """A file stored with flipped x and y (an LPS-ordered NIfTI, re-oriented to RAS+ on reading) or read with pad=:
    the voxel indices of the file are still recognised as the truth's frame."""
    m = boxes_mask()
    aff = np.diag([-0.5, -0.5, 0.8, 1.0])
    aff[:3, 3] = [30.0, 10.0, 3.2]
    nib.save(nib.Nifti1Image(m.astype(np.uint8), aff), str(tmp_path / "flipped.nii.gz"))
    _nifti(tmp_path / "plain.nii.gz", m.astype(np.uint8), spacing=(0.5, 0.5, 0.8), origin=(12.0, -7.5, 3.2))
    v, f = voxel_surface(m, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0])     # the surface in the file's voxel indices
    trimesh.Trimesh(v, f, process=False).export(str(tmp_path / "index.obj"))
    for spec in (f"volume:{tmp_path / 'flipped.nii.gz'}?truth={tmp_path / 'index.obj'}",
                 f"volume:{tmp_path / 'plain.nii.gz'}?pad=2&truth={tmp_path / 'index.obj'}"):
        with pytest.raises(InputError, match="fits the volume in voxel-index coordinates of the file"):
            get_phantom(spec)
