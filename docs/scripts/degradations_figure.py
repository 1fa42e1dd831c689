"""Draw docs/img/degradations.png: the bunny's mid-y slice as each degradation gives it (docs/PHANTOMS.md).

    python docs/scripts/degradations_figure.py

Each panel is the image a method receives (``Volume.raw``), the exact surface's slice drawn over it in red.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from phantoms import get_phantom  # noqa: E402
from phantoms.degrade import degrade  # noqa: E402

SPECS = ["mask", "partial_volume", "thick_slices@3+mask", "thick_slices@3+partial_volume", "blur@1.5+partial_volume",
         "mask+label_noise@0.3"]


def main(n: int = 48, out: Path = Path(__file__).resolve().parents[1] / "img" / "degradations.png") -> None:
    ph = get_phantom("bunny")
    exact = ph.volume(n=n)
    j = n // 2
    fig, axes = plt.subplots(1, len(SPECS), figsize=(3 * len(SPECS), 3.2))
    for ax, spec in zip(axes, SPECS):
        vol = degrade(ph, spec, n, seed=0)
        y = int(round((exact.origin[1] + j * exact.spacing[1] - vol.origin[1]) / vol.spacing[1]))
        img = vol.raw[:, y, :].T
        half = vol.spacing / 2                                  # a pixel is the voxel around its centre
        ext = [vol.lower[0] - half[0], vol.upper[0] + half[0], vol.lower[2] - half[2], vol.upper[2] + half[2]]
        ax.imshow(img, origin="lower", cmap="gray", extent=ext, interpolation="nearest", vmin=0, vmax=1,
                  aspect="equal")
        ax.contour(exact.values[:, j, :].T, levels=[0], colors="red", linewidths=0.8, origin="lower",
                   extent=[exact.lower[0], exact.upper[0], exact.lower[2], exact.upper[2]])
        ax.set_title(spec, fontsize=9)
        ax.set_xlim(-1.6, 1.6)
        ax.set_ylim(-1.6, 1.6)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle(f"bunny, N = {n}, slice y = 0 (x right, z up): the image each degradation gives; "
                 "red: the exact surface", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=90)
    print(out)


if __name__ == "__main__":
    main()
