"""Issue 44's development / held-out shapes: copy public genus-0 meshes out of three test-model repositories,
keep only those that are closed, one piece and of Euler characteristic 2 as published (no repair), and split
them into a development and a held-out half — stratified by kind, seeded — before any tuning.

The meshes are never committed (their licences differ, see docs/NOTES.md) and the tests never read them: this
script writes them to ``OUT/dev/`` and ``OUT/heldout/`` (``.obj``; an ``.off`` source is only re-written as
``.obj``) with ``OUT/manifest.tsv`` (name, kind, split, source repository, path, licence). The repositories are
bare git directories (``git --git-dir=GITDIR show HEAD:PATH``), e.g. the search tools' ``fetch`` mirrors::

    python docs/scripts/issue44_shapes.py --out /work/shapes \\
        --repo alecjacobson/common-3d-test-models=/work/.mirror/alecjacobson+common-3d-test-models/repo \\
        --repo odedstein/meshes=/work/.mirror/odedstein+meshes/repo \\
        --repo libigl/libigl-tutorial-data=/work/.mirror/libigl+libigl-tutorial-data/repo/.git

Split: within each kind the names are sorted, permuted with ``numpy.random.default_rng(44)`` and dealt
alternately to dev and held-out (the first to held-out), so every kind is on both sides.

``--fresh`` writes instead the later addition to the held-out part (``OUT/fresh6/``, :data:`FRESH`): shapes
published with texture seams (merged by position) or as tetrahedral meshes (their boundary), declared before any
method ran on them. A mesh whose parts cross is left out after the split (the suite refuses it as a truth).
"""
from __future__ import annotations

import argparse
import io
import subprocess
from pathlib import Path

import numpy as np

#: (name, kind, repository, path in it, licence as the repository states it)
SHAPES = [
    ("armadillo", "animal", "odedstein/meshes", "objects/armadillo/armadillo.obj",
     "Stanford 3D Scanning Repository terms (research, credit)"),
    ("cat", "animal", "odedstein/meshes", "objects/cat/cat-low-resolution.obj", "CC BY 4.0"),
    ("scorpion", "animal", "odedstein/meshes", "objects/scorpion/scorpion.obj", "CC BY 3.0"),
    ("koala", "animal", "odedstein/meshes", "objects/koala/koala.obj", "CC BY 3.0"),
    ("penguin", "animal", "odedstein/meshes", "objects/penguin/penguin.obj", "not stated"),
    ("fish", "animal", "odedstein/meshes", "objects/fish/fish.obj", "not stated (Keenan Crane's model repository)"),
    ("goathead", "animal", "odedstein/meshes", "objects/goathead/goathead.obj", "CC BY 3.0"),
    ("horse", "animal", "libigl/libigl-tutorial-data", "horse_quad.obj", "not stated"),
    ("elephant", "animal", "libigl/libigl-tutorial-data", "elephant.obj", "not stated"),
    ("cheburashka", "character", "alecjacobson/common-3d-test-models", "data/cheburashka.obj", "not stated"),
    ("homer", "character", "alecjacobson/common-3d-test-models", "data/homer.obj", "not stated"),
    ("nefertiti", "character", "alecjacobson/common-3d-test-models", "data/nefertiti.obj", "not stated"),
    ("human_man", "character", "odedstein/meshes", "objects/human/human_man.obj", "SMPL body licence"),
    ("human_woman", "character", "odedstein/meshes", "objects/human/human_woman.obj", "SMPL body licence"),
    ("falconstatue", "character", "odedstein/meshes", "objects/falconstatue/falconstatue.obj", "CC BY-NC-SA 4.0"),
    ("springer", "character", "odedstein/meshes", "objects/springer/springer.obj", "GPL-2.0"),
    ("max", "character", "libigl/libigl-tutorial-data", "decimated-max.obj", "not stated (MPI Saarbruecken)"),
    ("knight", "character", "libigl/libigl-tutorial-data", "decimated-knight.off", "not stated (Cosmic blobs)"),
    ("fandisk", "mechanical", "alecjacobson/common-3d-test-models", "data/fandisk.obj", "not stated"),
    ("hammer", "mechanical", "odedstein/meshes", "objects/hammer/hammer.obj", "CC BY 4.0"),
    ("sword", "mechanical", "odedstein/meshes", "objects/sword/sword.obj", "CC BY 4.0"),
    ("wingnut", "mechanical", "odedstein/meshes", "objects/wingnut/wingnut.obj", "CC BY 4.0"),
    ("screwdriver", "mechanical", "libigl/libigl-tutorial-data", "screwdriver.off", "not stated"),
    ("bumpy_cube", "mechanical", "libigl/libigl-tutorial-data", "bumpy-cube.obj", "not stated"),
    ("hand", "organ", "odedstein/meshes", "objects/hand/hand_closed.obj", "SMPL body licence"),
    ("arm", "organ", "libigl/libigl-tutorial-data", "arm.obj", "not stated"),
    ("bumpy", "organ", "libigl/libigl-tutorial-data", "bumpy.off", "not stated"),
]


#: the fresh addition (``--fresh``): (name, kind, repository, path, licence)
FRESH = [
    ("spot", "animal", "odedstein/meshes", "objects/spot/spot.obj", "CC0 (Keenan Crane)"),
    ("hand_tet", "organ", "libigl/libigl-tutorial-data", "hand.mesh", "not stated"),
    ("octopus", "animal", "libigl/libigl-tutorial-data", "octopus-low.mesh", "not stated"),
]


def genus0_reason(mesh) -> str | None:
    """Why ``mesh`` is not one closed genus-0 surface (None when it is): watertight, χ = 2, one body."""
    if not mesh.is_watertight:
        return "not watertight"
    if mesh.euler_number != 2:
        return f"Euler characteristic {mesh.euler_number}"
    bodies = len(mesh.split(only_watertight=False))
    return None if bodies == 1 else f"{bodies} pieces"


def crossing_reason(mesh) -> str | None:
    """Why ``mesh`` is no truth although closed (None when it is one): parts that cross.  Checked after the
    split, so the split stays the one declared before the check existed."""
    from geometry.intersections import crossing_pairs

    crossing = len(crossing_pairs(mesh.vertices, mesh.faces))
    return f"{crossing} pairs of faces cross" if crossing else None


def medit_boundary(data: bytes):
    """The boundary surface (a trimesh) of a MEDIT ``.mesh`` tetrahedral mesh: the faces of one tetrahedron only,
    oriented outwards."""
    import trimesh

    tok = data.decode().split()
    at = {t: i for i, t in enumerate(tok) if t in ("Vertices", "Tetrahedra")}
    nv, nt = int(tok[at["Vertices"] + 1]), int(tok[at["Tetrahedra"] + 1])
    v = np.array(tok[at["Vertices"] + 2:at["Vertices"] + 2 + 4 * nv], float).reshape(nv, 4)[:, :3]
    t = np.array(tok[at["Tetrahedra"] + 2:at["Tetrahedra"] + 2 + 5 * nt], int).reshape(nt, 5)[:, :4] - 1
    f = np.concatenate([t[:, [0, 2, 1]], t[:, [0, 1, 3]], t[:, [0, 3, 2]], t[:, [1, 2, 3]]])
    _, inverse, count = np.unique(np.sort(f, axis=1), axis=0, return_inverse=True, return_counts=True)
    mesh = trimesh.Trimesh(v, f[count[inverse.ravel()] == 1], process=True)
    mesh.remove_unreferenced_vertices()
    trimesh.repair.fix_normals(mesh)
    return mesh


def read_shape(data: bytes, path: str):
    """The published mesh as one surface: a tetrahedral mesh's boundary, texture seams merged by position."""
    import trimesh

    if path.endswith(".mesh"):
        return medit_boundary(data)
    mesh = trimesh.load(io.BytesIO(data), file_type=Path(path).suffix[1:], force="mesh")
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    return mesh


def split(names_by_kind: dict[str, list[str]], seed: int = 44) -> dict[str, str]:
    """Each name's side, 'heldout' or 'dev': per kind, sorted, permuted by the seed and dealt alternately."""
    rng = np.random.default_rng(seed)
    side = {}
    for kind in sorted(names_by_kind):
        names = sorted(names_by_kind[kind])
        for i, j in enumerate(rng.permutation(len(names))):
            side[names[j]] = "heldout" if i % 2 == 0 else "dev"
    return side


def main(argv=None) -> None:
    """Copy, check, split; print one line per shape and write the manifest."""
    import trimesh

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--repo", action="append", default=[], help="owner/name=GITDIR")
    ap.add_argument("--fresh", action="store_true", help="write the fresh addition to OUT/fresh6 instead")
    args = ap.parse_args(argv)
    gitdirs = dict(r.split("=", 1) for r in args.repo)
    kept = {}
    for name, kind, repo, path, licence in FRESH if args.fresh else SHAPES:
        data = subprocess.run(["git", "--git-dir", gitdirs[repo], "show", f"HEAD:{path}"],
                              capture_output=True, check=True).stdout
        mesh = read_shape(data, path) if args.fresh else trimesh.load(
            io.BytesIO(data), file_type=Path(path).suffix[1:], force="mesh")
        reason = genus0_reason(mesh)
        print(f"{name:14s} {kind:11s} {len(mesh.faces):7d} faces  {reason or 'kept'}")
        if reason is None:
            kept[name] = (kind, repo, path, licence, data, mesh)
    by_kind: dict[str, list[str]] = {}
    for name, (kind, *_rest) in kept.items():
        by_kind.setdefault(kind, []).append(name)
    side = {name: "fresh6" for name in kept} if args.fresh else split(by_kind)
    rows = ["name\tkind\tsplit\trepository\tpath\tlicence"]
    for name, (kind, repo, path, licence, data, mesh) in sorted(kept.items(), key=lambda kv: (side[kv[0]], kv[0])):
        if crossing_reason(mesh):
            print(f"{name:14s} left out ({side[name]}): {crossing_reason(mesh)}")
            continue
        folder = args.out / side[name]
        folder.mkdir(parents=True, exist_ok=True)
        if path.endswith(".obj") and not args.fresh:
            (folder / f"{name}.obj").write_bytes(data)
        else:
            mesh.export(folder / f"{name}.obj")
        rows.append("\t".join([name, kind, side[name], repo, path, licence]))
    (args.out / ("manifest_fresh6.tsv" if args.fresh else "manifest.tsv")).write_text("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
