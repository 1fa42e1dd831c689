"""Flying Edges (VTK vtkFlyingEdges3D): closed, outward, χ = 2 and within 1.5 h (Hausdorff) on the four paper
phantoms and the bunny at N = 48; the same vertex set as scikit-image marching cubes to 1e-6; world coordinates
on an anisotropic, off-centre grid; without VTK, one line naming the extra (the import failure is simulated)."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from scipy.spatial import cKDTree

from methods import get_method
from phantoms import InputError, save_volume

from _peers_common import (PAPER_PHANTOMS, RADIUS, check_closed_outward, hausdorff_h, offcentre_sphere,
                           sphere_errors, volume)

pytest.importorskip("vtkmodules.vtkFiltersCore", reason='VTK not installed: pip install "vtk>=9.3"')

N = 48


def _max_set_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Hausdorff distance between two point sets (each point's nearest neighbour in the other set)."""
    return max(float(cKDTree(b).query(a)[0].max()), float(cKDTree(a).query(b)[0].max()))


@pytest.mark.parametrize("phantom", PAPER_PHANTOMS + ["bunny"])
def test_closed_outward_and_close(phantom):
    vol = volume(phantom, N)
    rec = get_method("flying_edges").reconstruct(vol)
    check_closed_outward(rec.mesh, f"flying_edges on {phantom}")
    assert hausdorff_h(rec.mesh, phantom, vol.h) <= 1.5
    assert rec.info["iterations"] == 0 and rec.info["stop_reason"] == "done"


@pytest.mark.parametrize("phantom", PAPER_PHANTOMS + ["bunny", "cortex"])
def test_same_vertices_as_marching_cubes(phantom):
    """Flying Edges interpolates the same grid edges linearly as marching cubes: the same vertex set (both
    libraries return float32 positions, hence the 1e-6).  Lorensen's case table is the one VTK uses; Lewiner's
    (the suite's default) adds a vertex inside some ambiguous cells, which the bunny and the cortex have, so it
    is compared on the paper phantoms only."""
    vol = volume(phantom, N)
    fe = get_method("flying_edges").reconstruct(vol).mesh
    mc = get_method("marching_cubes", method="lorensen").reconstruct(vol).mesh
    assert len(fe.vertices) == len(mc.vertices) and len(fe.faces) == len(mc.faces)
    assert _max_set_distance(np.asarray(fe.vertices), np.asarray(mc.vertices)) < 1e-6
    if phantom in PAPER_PHANTOMS:
        lewiner = get_method("marching_cubes").reconstruct(vol).mesh
        assert _max_set_distance(np.asarray(fe.vertices), np.asarray(lewiner.vertices)) < 1e-6


def test_world_coordinates_anisotropic_offcentre():
    vol = offcentre_sphere()
    assert len(set(vol.shape)) == 3 and len(set(vol.spacing)) == 3
    rec = get_method("flying_edges").reconstruct(vol)
    check_closed_outward(rec.mesh, "flying_edges on the off-centre sphere")
    err, centre_offset = sphere_errors(rec.mesh)
    # linear interpolation of an exact SDF: second-order error, far below the spacing
    assert err < 0.05 * vol.spacing.min()
    assert np.abs(centre_offset).max() < 0.05 * vol.spacing.min()
    assert rec.mesh.volume == pytest.approx(4 / 3 * np.pi * RADIUS**3, rel=0.01)
    mc = get_method("marching_cubes", method="lorensen").reconstruct(vol).mesh
    assert _max_set_distance(np.asarray(rec.mesh.vertices), np.asarray(mc.vertices)) < 1e-6


def test_level_moves_the_surface_and_is_checked():
    vol = offcentre_sphere()
    rec = get_method("flying_edges", level=0.1).reconstruct(vol)
    r = np.linalg.norm(rec.mesh.vertices - np.array([0.31, -0.22, 0.13]), axis=1)
    assert np.abs(r - (RADIUS + 0.1)).max() < 0.05 * vol.spacing.min()
    with pytest.raises(InputError, match="parameter 'level'.*outside the volume's values"):
        get_method("flying_edges", level=1e5).reconstruct(vol)


def test_the_volume_is_not_copied(monkeypatch):
    """The array VTK reads is the volume's own buffer (no transposed copy)."""
    from vtkmodules.util import numpy_support

    seen = []
    original = numpy_support.numpy_to_vtk

    def spy(array, *args, **kwargs):
        seen.append(array)
        return original(array, *args, **kwargs)

    monkeypatch.setattr(numpy_support, "numpy_to_vtk", spy)
    vol = volume("sphere", 24)
    get_method("flying_edges").reconstruct(vol)
    assert len(seen) == 1 and np.shares_memory(seen[0], vol.values)


def test_without_vtk_one_line_naming_the_extra(monkeypatch, tmp_path, capsys):
    # a None entry in sys.modules makes `import` raise ImportError, as if VTK were not installed
    for mod in ("vtkmodules.util", "vtkmodules.util.numpy_support", "vtkmodules.vtkCommonDataModel",
                "vtkmodules.vtkFiltersCore"):
        monkeypatch.setitem(sys.modules, mod, None)
    with pytest.raises(InputError) as exc:
        get_method("flying_edges").reconstruct(volume("sphere", 24))
    msg = str(exc.value)
    assert "\n" not in msg and "flying_edges" in msg and 'pip install "vtk>=9.3"' in msg
    # the command line: exit code 2, the one line, no traceback
    from bench.cli import main

    path = tmp_path / "sphere.npz"
    save_volume(path, volume("sphere", 24))
    assert main(["reconstruct", str(path), "-m", "flying_edges", "-o", str(tmp_path / "out.ply")]) == 2
    err = capsys.readouterr().err
    assert 'pip install "vtk>=9.3"' in err and "Traceback" not in err
