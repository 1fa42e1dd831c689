"""bench/metrics/data_topology.py: the input's digital topology against the mesh's — constructed masks with a
cavity, two parts and a handle; meshes that fill, merge, drop or cut are flagged with the right kind, correct ones
(marching cubes and surface nets of the mask, a smooth mesh of a noisy φ) are not."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import ndimage

from bench.metrics import evaluate
from bench.metrics.data_topology import (KINDS, MIN_VOXELS, data_topology_metrics, digital_topology,
                                         euler_characteristic, mesh_shells)
from bench.metrics.flags import is_usable, result_flags
from phantoms import Volume, add_noise, mask_to_sdf

N = 28
SPACING = np.array([0.5, 0.5, 0.7])            # anisotropic, a non-zero origin: world coordinates are exercised
ORIGIN = np.array([1.0, -2.0, 0.5])


def _grid():
    return np.indices((N, N, N)).astype(float)


def hollow_ball() -> np.ndarray:
    """A ball of radius 10 voxels with a cavity of radius 5: one part, one cavity."""
    r = np.sqrt(((_grid() - 13.5) ** 2).sum(0))
    return (r < 10) & (r >= 5)


def two_balls() -> np.ndarray:
    """Two balls of radius 5 voxels, 4 voxels apart."""
    g = _grid()
    a = np.sqrt((g[0] - 8) ** 2 + (g[1] - 13.5) ** 2 + (g[2] - 13.5) ** 2) < 5
    b = np.sqrt((g[0] - 21) ** 2 + (g[1] - 13.5) ** 2 + (g[2] - 13.5) ** 2) < 5
    return a | b


def torus() -> np.ndarray:
    """A ring of major radius 8, tube radius 3 voxels: one handle."""
    g = _grid() - 13.5
    q = np.sqrt(g[0] ** 2 + g[1] ** 2)
    return (q - 8) ** 2 + g[2] ** 2 < 9


def mask_volume(mask: np.ndarray) -> Volume:
    sdf = mask_to_sdf(mask, ORIGIN, SPACING).values
    return Volume(sdf, ORIGIN, SPACING, kind="mask", raw=mask.astype(float), level=0.5)


def mc(mask_or_volume) -> trimesh.Trimesh:
    """The suite's marching cubes of a mask (through its signed distance) or of a volume."""
    from methods.isosurface import marching_cubes_mesh

    vol = mask_or_volume if isinstance(mask_or_volume, Volume) else mask_volume(mask_or_volume)
    return marching_cubes_mesh(vol)


def detail(mesh, vol) -> str:
    out: dict = {}
    evaluate(mesh, None, vol.h, volume=vol, n_samples=2000, details=out)
    return out["topology_vs_data"]


def kinds(text: str) -> set[str]:
    return {part.split(":")[0] for part in text.split("; ") if part}


# ------------------------------------------------------------------ the data's digital topology

def test_euler_characteristic_is_scikit_images_for_both_connectivities():
    from skimage.measure import euler_number

    rng = np.random.default_rng(3)
    for _ in range(10):
        m = rng.random((9, 8, 7)) < rng.uniform(0.2, 0.8)
        assert euler_characteristic(m, 6) == euler_number(m, connectivity=1)
        assert euler_characteristic(m, 26) == euler_number(m, connectivity=3)


@pytest.mark.parametrize("make, parts, cavities, handles", [(hollow_ball, 1, 1, 0), (two_balls, 2, 0, 0),
                                                            (torus, 1, 0, 1)])
def test_the_constructed_masks_have_their_hand_counted_topology(make, parts, cavities, handles):
    t = digital_topology(make())
    for pair in ((6, 26), (26, 6)):
        p = t["pairs"][pair]
        assert (p["parts_big"], p["cavities_big"], p["handles"], p["speckles"]) == (parts, cavities, handles, 0)


def test_contacts_at_an_edge_or_a_corner_are_one_part_or_two_and_a_voxel_gap_is_two():
    m = np.zeros((10, 10, 10), bool)
    m[1:4, 1:4, 1:4] = True
    corner = m.copy()
    corner[4:7, 4:7, 4:7] = True                      # touching the first block at one corner
    t = digital_topology(corner)["pairs"]
    assert t[(6, 26)]["parts"] == 2 and t[(26, 6)]["parts"] == 1
    gap = m.copy()
    gap[5:8, 1:4, 1:4] = True                         # one voxel apart
    t = digital_topology(gap)["pairs"]
    assert t[(6, 26)]["parts"] == t[(26, 6)]["parts"] == 2
    # a cavity whose wall has a diagonal chain of holes meeting at corners only: open for the 26-connected outside;
    # for the 6-connected one the cavity stays closed and the hole voxel (2, 2, 2) is a cavity of its own
    box = np.zeros((9, 9, 9), bool)
    box[1:8, 1:8, 1:8] = True
    box[3:6, 3:6, 3:6] = False
    box[2, 2, 2] = False                              # the cavity's corner voxel (3, 3, 3) meets it at a corner
    box[1, 1, 1] = False
    t = digital_topology(box)["pairs"]
    assert t[(6, 26)]["cavities"] == 0 and t[(26, 6)]["cavities"] == 2


def test_speckles_are_counted_and_not_required():
    m = two_balls()
    m[1, 1, 1] = True                                 # a one-voxel part
    m[8, 13, 13] = False                              # a one-voxel cavity inside the first ball
    p = digital_topology(m)["pairs"][(6, 26)]
    assert p["parts"] == 3 and p["parts_big"] == 2 and p["cavities"] == 1 and p["cavities_big"] == 0
    assert p["speckles"] == 2 and MIN_VOXELS > 1
    # the marching cubes of the clean balls leaves both speckles out and is consistent with the data
    assert detail(mc(two_balls()), mask_volume(m)) == ""


# ------------------------------------------------------------------ the mesh's shells

def test_a_hollow_balls_mesh_has_one_part_one_void_and_a_tori_genus_one():
    s = mesh_shells(*_arrays(mc(hollow_ball())))
    assert s["n"] == 2 and (s["volume"] > 0).sum() == 1 and (s["volume"] < 0).sum() == 1 and s["closed"].all()
    assert s["genus"].tolist() == [0, 0]
    s = mesh_shells(*_arrays(mc(torus())))
    assert s["n"] == 1 and s["genus"].tolist() == [1]


def _arrays(mesh):
    return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int64)


# ------------------------------------------------------------------ correct meshes are not flagged

@pytest.mark.parametrize("make", [hollow_ball, two_balls, torus])
def test_marching_cubes_of_the_mask_is_consistent(make):
    vol = mask_volume(make())
    assert detail(mc(vol), vol) == ""


@pytest.mark.parametrize("make", [hollow_ball, two_balls, torus])
def test_surface_nets_of_the_mask_is_consistent(make):
    pytest.importorskip("vtkmodules")
    from methods import get_method

    vol = mask_volume(make())
    try:
        mesh = get_method("surface_nets").reconstruct(vol).mesh
    except Exception as exc:               # VTK < 9.3 has no SurfaceNets3D
        pytest.skip(f"surface nets unavailable: {exc}")
    assert detail(mesh, vol) == ""


def test_a_smooth_mesh_of_a_noisy_level_set_is_not_flagged():
    """The torus's signed distance with noise of σ ≈ 0.6 h: φ < 0 has dozens of speckles and 8–15 handles where the
    torus has one; the clean marching cubes (what a perfect smoother would return) and the noisy one are both
    consistent."""
    g = (_grid() - 13.5) * 0.5
    q = np.sqrt(g[0] ** 2 + g[1] ** 2)
    clean = Volume(np.sqrt((q - 4.0) ** 2 + g[2] ** 2) - 1.5, ORIGIN, 0.5)
    noisy, _ = add_noise(clean, "gaussian", 21.0, seed=1)
    sigma = np.std(noisy.values - clean.values) / clean.h
    p = digital_topology(noisy.inside_raw)["pairs"][(6, 26)]
    assert 0.5 < sigma < 0.7 and p["speckles"] > 20 and p["handles"] > 5     # the noise made it speckled
    assert detail(mc(clean), noisy) == ""
    assert detail(mc(noisy), noisy) == ""


# ------------------------------------------------------------------ wrong meshes are flagged with their kind

def test_a_mesh_that_fills_the_cavity_is_flagged_filled_cavities():
    vol = mask_volume(hollow_ball())
    text = detail(mc(ndimage.binary_fill_holes(hollow_ball())), vol)
    assert kinds(text) == {"filled cavities"} and "filled cavities: 1 in data, 0 in mesh" in text


def test_a_mesh_that_merges_the_two_parts_is_flagged_merged_parts():
    bridged = two_balls()
    bridged[8:22, 12:16, 12:16] = True
    text = detail(mc(bridged), mask_volume(two_balls()))
    assert kinds(text) == {"merged parts"} and "merged parts: 2 in data, 1 in mesh" in text


def test_a_mesh_that_drops_a_part_is_flagged_dropped_parts():
    one = two_balls()
    one[15:] = False
    text = detail(mc(one), mask_volume(two_balls()))
    assert kinds(text) == {"dropped parts"} and "dropped parts: 1 of 2 in data" in text


def test_a_mesh_that_cuts_the_handle_is_flagged_closed_handles():
    cut = torus()
    cut[12:16, :14] = False                            # a slab through one side of the ring
    assert digital_topology(cut)["pairs"][(6, 26)]["handles"] == 0
    text = detail(mc(cut), mask_volume(torus()))
    assert kinds(text) == {"closed handles"} and "closed handles: 1 in data, 0 in mesh" in text


def test_a_mesh_with_a_handle_the_data_lacks_is_flagged_opened_handles():
    vol = mask_volume(two_balls())
    bridged = two_balls()
    bridged[8:22, 12:16, 8:10] = True                  # two bridges: one part, and a ring through them
    bridged[8:22, 12:16, 17:19] = True
    text = detail(mc(bridged), vol)
    assert kinds(text) == {"merged parts", "opened handles"}
    assert set(kinds(text)) <= set(KINDS)


def test_a_mesh_with_an_extra_part_and_an_extra_cavity_is_flagged():
    m = hollow_ball()
    extra = m.copy()
    extra[1:4, 1:4, 1:4] = True                        # a 27-voxel part the data does not have
    extra[12:15, 12:15, 5:8] = False                   # ... and a new 27-voxel cavity in the wall
    text = detail(mc(extra), mask_volume(m))
    assert kinds(text) == {"extra parts", "extra cavities"}


# ------------------------------------------------------------------ the columns, the flag, the usable board

def test_the_columns_and_the_flag_on_a_row_with_and_without_truth():
    vol = mask_volume(two_balls())
    one = two_balls()
    one[15:] = False
    cols, text = data_topology_metrics(*_arrays(mc(one)), vol)
    assert cols["data_parts"] == 2 and cols["data_cavities"] == 0 and cols["mesh_voids"] == 0
    assert cols["topology_diffs"] == 1 and text
    row = {"status": "ok", "topology_vs_data_detail": text, "euler": 2, "components": 1}
    assert "topology_vs_data" in result_flags(row)
    without = {**row, "has_truth": False, "flags": ";".join(result_flags(row))}
    with_truth = {**without, "has_truth": True}
    assert not is_usable(without) and is_usable(with_truth)   # with a truth, the truth decides
    assert "topology_vs_data" not in result_flags({**row, "topology_vs_data_detail": ""})


def test_evaluate_without_a_volume_leaves_the_columns_nan():
    out = evaluate(trimesh.creation.icosphere(2), None, 0.1, n_samples=500)
    assert all(np.isnan(out[k]) for k in ("data_parts", "mesh_genus", "topology_diffs"))


def test_on_the_usable_board_of_cells_without_truth_a_mesh_that_merges_the_datas_parts_ranks_last():
    """Truth-free rows: 'one_piece' lies best on the data (smallest sdf_rms_h) but is flagged topology_vs_data on
    every input — it wins the raw board and ranks last on the usable one, usable on 0 % of its cells."""
    from bench.report.verdicts import leaderboards

    rows = []
    for i, v in enumerate(np.linspace(0.1, 0.3, 12)):
        for label, scale, flags in (("one_piece", 0.5, "topology_vs_data"), ("a", 1.0, ""), ("b", 1.4, "")):
            rows.append({"phantom": f"volume:scan{i}.nii.gz", "variant": "sdf", "N": 48, "noise": "none",
                         "snr_requested": None, "seed": 0, "label": label, "status": "ok", "flags": flags,
                         "has_truth": False, "wall_s": 1.0, "sdf_rms_h": v * scale, "phi_mean_h": v * scale,
                         "sign_err_pct": 0.01, "roughness_deg": 5.0})
    board = next(b for b in leaderboards(rows) if b.get("raw_board"))     # the truth-free board: the only one
    raw = board["raw_board"]                                              # the raw values, usable or not
    assert raw["rows"][0]["label"] == "one_piece" and raw["rows"][0]["usable_pct"] == 0.0
    assert [r["label"] for r in board["rows"]] == ["a", "b", "one_piece"]  # the verdict's board
    assert board["rows"][0]["usable_pct"] == 100.0 and board["rows"][-1]["usable_pct"] == 0.0


def test_one_piece_where_the_data_has_many_parts_is_flagged_merged_with_both_counts():
    """A label map in 32 blocks of 3³ voxels, 3 voxels apart; the mesh of the blocks dilated together (one slab,
    as a smooth method started from one sphere returns): merged parts, 32 in data and 1 in mesh."""
    m = np.zeros((N, N, N), bool)
    for x in (2, 8, 14, 20):
        for y in (2, 8, 14, 20):
            for z in (2, 8):
                m[x:x + 3, y:y + 3, z:z + 3] = True
    blob = ndimage.binary_dilation(m, iterations=2)
    assert ndimage.label(blob)[1] == 1
    text = detail(mc(blob), mask_volume(m))
    assert text == "merged parts: 32 in data, 1 in mesh"
