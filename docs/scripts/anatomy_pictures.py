"""Draw a picture of each anatomy phantom (docs/PHANTOMS.md, "Anatomy phantoms"): its exact surface, shaded,
cut open where the inside matters (vault, cavities, socket), beside the mid-slice of its N = 48 mask with the exact
surface's slice (the truth mesh cut by the plane) in red.

    python docs/scripts/anatomy_pictures.py [OUT_DIR]      # default docs/img/: anatomy_<name>.png

Off-screen (matplotlib's Agg backend); the pictures are generated, not committed.
"""

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from phantoms import get_phantom  # noqa: E402
from phantoms.anatomy import ANATOMY  # noqa: E402
from phantoms.degrade import degrade  # noqa: E402

#: phantoms drawn cut open by the plane y = 0 (their inside is the point)
CUT = {"cavity_solid", "touching_pair"}
LIGHT = np.array([0.4, -0.5, 0.77])


def _surface(ax, ph) -> None:
    v, f = ph.vertices, ph.faces
    keep = v[f].mean(axis=1)[:, 1] > 0 if ph.name in CUT else np.ones(len(f), bool)   # behind the cut plane
    tri = v[f[keep]]
    shade = 0.35 + 0.65 * np.clip(ph.face_normals[keep] @ (LIGHT / np.linalg.norm(LIGHT)), 0, 1)
    colours = plt.cm.bone(0.25 + 0.7 * shade)
    ax.add_collection3d(Poly3DCollection(tri, facecolors=colours, edgecolors="none", linewidths=0))
    lim = 1.9
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_zlim(-lim, lim)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(elev=20, azim=-60)
    ax.set_axis_off()


def _slice(ax, ph, n: int = 48) -> None:
    vol = degrade(ph, "mask", n)
    j = n // 2
    y = vol.origin[1] + j * vol.spacing[1]
    half = vol.spacing / 2
    ext = [vol.lower[0] - half[0], vol.upper[0] + half[0], vol.lower[2] - half[2], vol.upper[2] + half[2]]
    ax.imshow(vol.raw[:, j, :].T, origin="lower", cmap="gray", extent=ext, interpolation="nearest", vmin=0, vmax=1)
    # the exact surface's slice: the truth mesh cut by the plane (a grid's contour would miss sub-voxel gaps)
    lines = trimesh.intersections.mesh_plane(trimesh.Trimesh(ph.vertices, ph.faces, process=False),
                                             [0.0, 1.0, 0.0], [0.0, y, 0.0])
    ax.add_collection(LineCollection(lines[:, :, [0, 2]], colors="red", linewidths=0.6))
    ax.set_xlim(-2, 2)
    ax.set_ylim(-2, 2)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(f"mask at N = {n}, mid slice; red: the exact surface", fontsize=9)


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for name in ANATOMY:
        ph = get_phantom(name)
        fig = plt.figure(figsize=(8, 4))
        ax = fig.add_subplot(1, 2, 1, projection="3d")
        _surface(ax, ph)
        ax.set_title(f"{name} ({ph.shape_kind}): {ph.n_components} component(s), genus {ph.genus}", fontsize=9)
        _slice(fig.add_subplot(1, 2, 2), ph)
        fig.tight_layout()
        path = out / f"anatomy_{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        print(f"wrote {path}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1] / "img")
