"""A reference surface or segmentation in the wrong frame or of the wrong kind (cause 17), tried as a new user
would: voxel indices, LPS, centimetres, an offset, an intensity image, an open mesh, a missing file.  Each is
refused before any cell, in one line naming the likely frame; a truth in the volume's world frame is used."""

from __future__ import annotations

from pathlib import Path

import nibabel as nib
import numpy as np
import trimesh

from .core import Case, Ctx, exits_ok, first, one_line, rows

ORIGIN = np.array([10.0, -20.0, 30.0])
SPACING = np.array([0.5, 0.6, 0.8])
SHAPE = (24, 22, 18)
CENTRE = ORIGIN + (np.array(SHAPE) - 1) * SPACING / 2 + [0.3, -0.2, 0.1]
RADIUS = 4.0


def scan(ctx: Ctx) -> Path:
    """A NIfTI mask of a 4 mm ball on an anisotropic grid away from the origin, its truths, an intensity
    image; made once, returns the folder."""
    def make() -> Path:
        d = ctx.root / "truth"
        d.mkdir(exist_ok=True)
        idx = np.stack(np.meshgrid(*[np.arange(s) for s in SHAPE], indexing="ij"), axis=-1)
        world = ORIGIN + idx * SPACING
        dist = np.linalg.norm(world - CENTRE, axis=-1)
        aff = np.diag([*SPACING, 1.0])
        aff[:3, 3] = ORIGIN
        nib.save(nib.Nifti1Image((dist < RADIUS).astype(np.uint8), aff), str(d / "seg.nii.gz"))
        nib.save(nib.Nifti1Image((1000 * np.clip(RADIUS + 0.5 - dist, 0, 1)).astype(np.float32), aff),
                 str(d / "ct.nii.gz"))
        nib.save(nib.Nifti1Image((400 + 600 * np.clip(RADIUS + 0.5 - dist, 0, 1)).astype(np.float32), aff),
                 str(d / "mri.nii.gz"))
        ball = trimesh.creation.icosphere(subdivisions=3, radius=RADIUS)
        v = ball.vertices + CENTRE
        frames = {"world": v, "index": (v - ORIGIN) / SPACING, "lps": v * [-1, -1, 1], "cm": v / 10,
                  "metres": v / 1000, "offset": v + [5.0, 0, 0], "scaled": (v - CENTRE) * 2 + CENTRE}
        for name, verts in frames.items():
            trimesh.Trimesh(verts, ball.faces, process=False).export(str(d / f"{name}.obj"))
        trimesh.Trimesh(v, ball.faces, process=False).export(str(d / "world.ply"))
        trimesh.Trimesh(v, ball.faces[:-10], process=False).export(str(d / "open.obj"))
        (d / "empty.obj").write_text("")
        bad = v.copy()
        bad[0] = np.nan
        (d / "nan.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in bad)
                                   + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in ball.faces))
        return d
    return ctx.once("truth.scan", make)


def info(ctx: Ctx, truth: str):
    d = scan(ctx)
    return ctx.bench("info", f"volume:{d}/seg.nii.gz?truth={d}/{truth}")


WRONG = {
    "a surface in voxel-index coordinates": ("index.obj", ("index",)),
    "a surface in LPS coordinates": ("lps.obj", ("LPS",)),
    "a surface in centimetres": ("cm.obj", ("cm.obj",)),
    "a surface in metres": ("metres.obj", ("metres.obj",)),
    "a surface 5 mm off in x": ("offset.obj", ("offset.obj",)),
    "a surface twice the size": ("scaled.obj", ("scaled.obj",)),
    "an intensity image (CT-like) as truth": ("ct.nii.gz", ("ct.nii.gz",)),
    "an intensity image (MR-like, no zero) as truth": ("mri.nii.gz", ("mri.nii.gz",)),
    "an open surface": ("open.obj", ("open.obj",)),
    "an empty .obj": ("empty.obj", ("empty.obj",)),
    "a surface with a NaN vertex": ("nan.obj", ("nan.obj",)),
    "a missing file": ("nowhere.obj", ("nowhere.obj",)),
}


def _run(ctx: Ctx, truth: str, tag: str, *extra: str):
    d = scan(ctx)
    out = ctx.root / "truth" / f"run_{tag}"
    res = ctx.bench("run", "--phantoms", f"volume:{d}/seg.nii.gz?truth={d}/{truth}", "--noise", "none",
                    "--method", "marching_cubes", "--out", str(out), "--jobs", "1", "--no-report", *extra,
                    timeout=240)
    return res, out


def cases() -> list[Case]:
    """Each wrong truth refused by info and by run before any cell; world-frame truths used."""
    out: list[Case] = []
    for name, (file, words) in WRONG.items():
        out.append(Case("17", f"info: {name}", lambda ctx, f=file, w=words: one_line(info(ctx, f), *w)))
    for name, file, word in (("voxel-index coordinates", "index.obj", "voxel-index"),
                             ("LPS coordinates", "lps.obj", "LPS"), ("an intensity image", "ct.nii.gz", "intensity"),
                             ("a missing file", "nowhere.obj", "nowhere.obj")):
        def check(ctx, file=file, word=word):
            res, folder = _run(ctx, file, file.split(".")[0])
            return first(one_line(res, word), "a results.csv was written" if (folder / "results.csv").exists()
                         else None)
        out.append(Case("17", f"run: {name}, refused before any cell", check))
        out.append(Case("17", f"run --dry-run: {name}", lambda ctx, f=file, w=word: one_line(
            _run(ctx, f, "dry_" + f.split(".")[0], "--dry-run")[0], w)))
    for file in ("world.obj", "world.ply", "seg.nii.gz"):
        out.append(Case("17", f"control: info with truth={file} in the world frame", lambda ctx, f=file: exits_ok(
            info(ctx, f))))

    def run_ok(ctx):
        res, folder = _run(ctx, "world.obj", "world")
        got = rows(folder)
        if not got or got[0]["status"] != "ok" or float(got[0]["hausdorff_h"]) > 2.0:
            return f"the world-frame truth gave {[(r['status'], r['hausdorff_h']) for r in got]}"
        return exits_ok(res)
    out.append(Case("17", "control: run with a world-frame truth is ok and near it", run_ok))
    return out
