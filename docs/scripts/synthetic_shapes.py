"""Fresh genus-0 test shapes, made by a seeded generator: a held-out set no one has tuned on, for a look after the
public development / held-out split (issue 44) has been used up.

Three kinds, chosen for what separates the methods: ``limbs`` — an ellipsoidal body with 3–6 capsules whose radii
run from 0.3 to 2 voxels at N = 64 (a sub-voxel limb is what marching cubes loses and Reach for the Spheres keeps);
``fins`` — a body with 2–4 flat discs 0.3 to 1.5 voxels thick (a blade); ``blobs`` — 2–4 ellipsoids in a smooth
union, nothing thin (where the smooth methods should win).  Each implicit shape is meshed by marching cubes on a
grid of 0.15 voxel, decimated to at most ``--faces`` faces (quadric edge collapse, topology kept) and kept only if
it is, as written, closed, one piece and of Euler characteristic 2; otherwise the next draw is taken.  The meshes
are scaled so their bounding sphere has radius 1.5 (the suite's mesh phantoms do the same), so the voxel sizes
above hold at N = 64 on the default box.  They are written as ``OUT/<kind>_<i>.obj``::

    python docs/scripts/synthetic_shapes.py --out /work/shapes/synth --seed 20261205 --per-kind 4
    python -m bench run --phantoms "mesh:/work/shapes/synth/*.obj" --n 64 --noise none,gaussian@40 ...

Nothing here is read by the tests; the seed decides every shape, so a set is reproduced exactly from its seed.
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

H = 5.0 / 63.0          # the voxel at N = 64 on the default box [−2.5, 2.5]³
DX = 0.15 * H           # the meshing grid
R = 1.5                 # the bounding radius the suite scales meshes to


def _smin(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    """Polynomial smooth minimum (a fillet of about ``k``)."""
    h = np.clip(0.5 + 0.5 * (b - a) / k, 0.0, 1.0)
    return b * (1 - h) + a * h - k * h * (1 - h)


def _ellipsoid(p, c, radii, rot):
    q = (p - c) @ rot
    return (np.linalg.norm(q / radii, axis=-1) - 1.0) * radii.min()


def _capsule(p, a, b, r):
    ab = b - a
    t = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * ab), axis=-1) - r


def _rotation(rng) -> np.ndarray:
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q


def _direction(rng) -> np.ndarray:
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def _shape(kind: str, rng):
    """The implicit function of one draw, as a callable on (…, 3) points (scale: bounding radius about R)."""
    body_r = rng.uniform(0.55, 0.9, 3)
    body_rot = _rotation(rng)
    parts = [lambda p: _ellipsoid(p, np.zeros(3), body_r, body_rot)]
    if kind == "limbs":
        for _ in range(rng.integers(3, 7)):
            d = _direction(rng)
            r = H * float(np.exp(rng.uniform(np.log(0.3), np.log(2.0))))
            a, b = 0.3 * d, rng.uniform(1.1, 1.45) * d
            parts.append(lambda p, a=a, b=b, r=r: _capsule(p, a, b, r))
    elif kind == "fins":
        for _ in range(rng.integers(2, 5)):
            d = _direction(rng)
            t = H * float(np.exp(rng.uniform(np.log(0.3), np.log(1.5)))) / 2.0
            rad = np.array([rng.uniform(0.35, 0.6), rng.uniform(0.35, 0.6), t])
            rot = _rotation(rng)
            c = rng.uniform(0.7, 0.95) * d
            parts.append(lambda p, c=c, rad=rad, rot=rot: _ellipsoid(p, c, rad, rot))
    else:
        for _ in range(rng.integers(1, 4)):
            c = rng.uniform(0.4, 0.8) * _direction(rng)
            rad = rng.uniform(0.3, 0.6, 3)
            rot = _rotation(rng)
            parts.append(lambda p, c=c, rad=rad, rot=rot: _ellipsoid(p, c, rad, rot))
    k = 0.5 * H if kind != "blobs" else 0.15

    def f(p):
        out = parts[0](p)
        for g in parts[1:]:
            out = _smin(out, g(p), k)
        return out
    return f


def _mesh(f, faces: int):
    import pymeshlab
    import trimesh
    from skimage.measure import marching_cubes

    g = np.arange(-1.7, 1.7 + DX, DX)
    vals = np.empty((len(g),) * 3, dtype=np.float32)
    for i, x in enumerate(g):                                   # slab by slab: bounded memory
        p = np.stack(np.meshgrid([x], g, g, indexing="ij"), -1)[0]
        vals[i] = f(p)
    v, fc, _, _ = marching_cubes(vals, 0.0, spacing=(DX,) * 3)
    v += g[0]
    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(v, fc))
    if len(fc) > faces:
        ms.meshing_decimation_quadric_edge_collapse(targetfacenum=faces, preservetopology=True,
                                                    preservenormal=True, qualitythr=0.5)
    m = ms.current_mesh()
    mesh = trimesh.Trimesh(m.vertex_matrix(), m.face_matrix(), process=True)
    centre = 0.5 * (mesh.vertices.min(0) + mesh.vertices.max(0))
    mesh.vertices -= centre
    mesh.vertices *= R / np.linalg.norm(mesh.vertices, axis=1).max()
    return mesh


def _check(mesh) -> str | None:
    if not mesh.is_watertight:
        return "not closed"
    if len(mesh.split(only_watertight=False)) != 1:
        return "several pieces"
    if mesh.euler_number != 2:
        return f"Euler characteristic {mesh.euler_number}"
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--per-kind", type=int, default=4)
    ap.add_argument("--faces", type=int, default=60_000)
    a = ap.parse_args(argv)
    a.out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    for kind in ("limbs", "fins", "blobs"):
        made = 0
        while made < a.per_kind:
            mesh = _mesh(_shape(kind, rng), a.faces)
            why = _check(mesh)
            if why is not None:
                print(f"{kind}: draw dropped ({why})")
                continue
            path = a.out / f"{kind}_{made}.obj"
            mesh.export(path)
            print(f"{path}: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces")
            made += 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
