"""The unit sphere's mask on [-2.5, 2.5]^3 built with numpy (no degradation code), for the mask-native methods'
tests: kind 'mask' (raw 0/1 at level 0.5, values its signed distance), kind 'sdf', kind 'intensity'."""

import numpy as np

from phantoms import Volume, mask_to_sdf

BALL = 4 / 3 * np.pi
LO, HI = -2.5, 2.5


def _axes(n: int, z_factor: int):
    axes = [np.linspace(LO, HI, n), np.linspace(LO, HI, n), np.linspace(LO, HI, (n - 1) // z_factor + 1)]
    return axes, np.array([a[1] - a[0] for a in axes])


def sphere_mask(n: int = 48, z_factor: int = 1) -> Volume:
    """The mask r < 1 at the voxel centres; z spacing ``z_factor`` times the others (the same world box)."""
    axes, spacing = _axes(n, z_factor)
    x, y, z = np.meshgrid(*axes, indexing="ij")
    mask = x ** 2 + y ** 2 + z ** 2 < 1
    origin = np.full(3, LO)
    sdf = mask_to_sdf(mask, origin, spacing).values
    return Volume(sdf, origin, spacing, kind="mask", raw=mask.astype(float), level=0.5)


def sphere_sdf(n: int = 48) -> Volume:
    axes, spacing = _axes(n, 1)
    x, y, z = np.meshgrid(*axes, indexing="ij")
    return Volume(np.sqrt(x ** 2 + y ** 2 + z ** 2) - 1, np.full(3, LO), spacing)


def sphere_partial_volume(n: int = 48, sub: int = 4) -> Volume:
    """Each voxel's inside fraction (``sub``^3 samples), an intensity image at level 0.5."""
    axes, spacing = _axes(n, 1)
    frac = np.zeros((n, n, n))
    offsets = (np.arange(sub) + 0.5) / sub - 0.5
    for dx in offsets:
        for dy in offsets:
            for dz in offsets:
                x, y, z = np.meshgrid(axes[0] + dx * spacing[0], axes[1] + dy * spacing[1], axes[2] + dz * spacing[2],
                                      indexing="ij")
                frac += (x ** 2 + y ** 2 + z ** 2 < 1)
    frac /= sub ** 3
    sdf = sphere_sdf(n).values
    return Volume(sdf, np.full(3, LO), spacing, kind="intensity", raw=frac, level=0.5)


def facts(mesh, h: float) -> tuple[float, float]:
    """(enclosed volume / the ball's − 1, max |‖v‖ − 1| in units of h)."""
    r = np.linalg.norm(mesh.vertices, axis=1)
    return mesh.volume / BALL - 1, float(np.abs(r - 1).max() / h)


def closed_outward(mesh) -> bool:
    return bool(mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0 and mesh.euler_number == 2)


def in_world_box(mesh, spacing) -> bool:
    """The bounding box within one (coarsest) voxel of ±1 on every axis."""
    return bool(np.all(np.abs(mesh.bounds[0] + 1) <= spacing.max())
                and np.all(np.abs(mesh.bounds[1] - 1) <= spacing.max()))
