"""The start of the flow: the initial surface (a sphere enclosing the zero set, the paper's sphere or a user's
closed genus-0 mesh, checked), the target's topology against one genus-0 surface, the snapshot list."""

from __future__ import annotations

import numpy as np
import trimesh

from geometry.mesh import signed_volume
from geometry.sphere import fibonacci_sphere
from geometry.topology import connected_components, edge_face_counts, euler_characteristic, genus, is_oriented
from phantoms import InputError, Volume

#: the enclosing sphere of init='auto' clears the inside grid points by this many voxels
_INIT_MARGIN_VOXELS = 2.0
#: pieces of φ < 0 whose lowest saddle of φ lies below this many voxels are joined by the genus-0 start
#: (docs/METHOD.md, "The genus-0 start")
JOIN_BELOW_VOXELS = 0.5
#: the samples of a joining path are set to at most −this many voxels (a tube about a voxel wide)
JOIN_DEPTH_VOXELS = 0.5

__all__ = ["parse_snapshots", "prepare_init_mesh", "initial_surface", "enclosing_sphere", "genus0_surface",
           "target_topology"]


def parse_snapshots(value) -> tuple[int, ...]:
    if value is None or (isinstance(value, str) and value.strip().lower() in ("", "none")):
        return ()
    if isinstance(value, str):
        items = [v for v in value.replace(";", ",").replace(" ", ",").split(",") if v]
    elif isinstance(value, (int, np.integer)):
        items = [value]
    else:
        try:
            items = list(value)
        except TypeError:
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': expected iteration numbers, "
                             f"got {value!r}") from None
    out = []
    for v in items:
        try:
            f = float(v)
        except (TypeError, ValueError):
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': {v!r} is not an iteration "
                             "number") from None
        if f != int(f) or f < 0:
            raise InputError(f"method 'shape_gradient', parameter 'snapshots': {v!r} is not an iteration "
                             "number (>= 0)")
        out.append(int(f))
    return tuple(sorted(set(out)))


def prepare_init_mesh(mesh) -> tuple[np.ndarray, np.ndarray, bool]:
    """Validate a user's initial mesh: (vertices, faces, flipped).

    Accepts a ``trimesh.Trimesh``, a ``(vertices, faces)`` pair or a path trimesh can load.  Raises
    InputError unless the mesh is a single closed, consistently oriented, genus-0 surface without
    degenerate faces; an inward-oriented mesh is flipped (``flipped`` = True).
    """
    where = "method 'shape_gradient', parameter 'init_mesh'"
    if isinstance(mesh, str):
        try:
            mesh = trimesh.load(mesh, force="mesh", process=False)
        except Exception as exc:  # noqa: BLE001 - any loader failure is a user error here
            raise InputError(f"{where}: cannot load {mesh!r}: {exc}") from None
    if isinstance(mesh, trimesh.Trimesh):
        v, f = np.asarray(mesh.vertices, float), np.asarray(mesh.faces)
    else:
        try:
            v, f = mesh
            v = np.asarray(v, dtype=float)
            f = np.asarray(f)
        except (TypeError, ValueError):
            raise InputError(f"{where}: expected a trimesh.Trimesh, a (vertices, faces) pair or a path; "
                             f"got {type(mesh).__name__}") from None
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InputError(f"{where}: vertices must be (V, 3) and faces (F, 3); got {v.shape} and {f.shape}")
    if not np.issubdtype(f.dtype, np.integer):
        if not np.all(f == np.round(f)):
            raise InputError(f"{where}: faces must hold integer vertex indices")
        f = f.astype(np.int64)
    f = f.astype(np.int64)
    if not np.isfinite(v).all():
        raise InputError(f"{where}: vertices contain NaN or inf")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{where}: face indices out of range [0, {len(v) - 1}]")
    used = np.unique(f)
    if len(used) != len(v):
        raise InputError(f"{where}: {len(v) - len(used)} vertices are not used by any face")
    if np.any((f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])):
        raise InputError(f"{where}: some faces repeat a vertex")
    # every undirected edge in exactly two faces, once in each direction (closed and consistently oriented)
    _, counts = edge_face_counts(f, len(v))
    if np.any(counts != 2):
        bad = int((counts != 2).sum())
        raise InputError(f"{where}: the mesh is not closed — {bad} edges are not shared by exactly two faces "
                         "(the method needs a closed surface)")
    if not is_oriented(f, len(v)):
        raise InputError(f"{where}: the faces are not consistently oriented")
    euler = euler_characteristic(f, len(v))
    n_comp, _ = connected_components(f, len(v), by="face")
    if n_comp != 1:
        raise InputError(f"{where}: the mesh has {n_comp} connected components; the method needs one surface")
    if euler != 2:
        raise InputError(f"{where}: the mesh has Euler characteristic {euler} (genus {genus(euler)}); "
                         "the method needs a genus-0 (sphere-like) surface")
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    dbl = np.linalg.norm(cross, axis=1)
    if np.any(dbl <= 1e-12 * max(1.0, float(np.ptp(v, axis=0).max())) ** 2):
        raise InputError(f"{where}: {int((dbl <= 0).sum()) or 'some'} faces are degenerate (zero area)")
    flipped = signed_volume(v, f) < 0
    if flipped:
        f = f[:, ::-1].copy()
    return v.copy(), np.ascontiguousarray(f), flipped




def initial_surface(volume: Volume, *, init: str, init_mesh, edge_length: float, join_below: float,
                    init_vertices: int, init_radius: float, values: np.ndarray | None = None,
                    pinhole_below: float = 0.0):
    """(vertices, faces, flipped, facts) of the initial surface the parameters ask for, checked to lie in the grid.

    Parameters
    ----------
    volume : Volume
        The volume the flow will run on.
    init : {'genus0', 'auto', 'sphere'}
        ``'genus0'``: :func:`genus0_surface` of ``values``, or the enclosing sphere if that fails; ``'auto'``:
        :func:`enclosing_sphere` at ``edge_length``; ``'sphere'``: the Fibonacci sphere of ``init_vertices`` /
        ``init_radius`` about the centre of the grid box.
    init_mesh : object or None
        A user's closed genus-0 mesh (:func:`prepare_init_mesh`); given, it is the start whatever ``init`` says.
    edge_length : float
        Edge length of the enclosing sphere, in voxels.
    join_below : float
        ``init='genus0'``: join the pieces of φ < 0 whose lowest saddle is below this many voxels.
    init_vertices : int
        Vertices of the Fibonacci sphere.
    init_radius : float
        Radius of the Fibonacci sphere (world units).
    values : ndarray, optional
        The samples the genus-0 start is grown from (default: the volume's; the method passes pre-smoothed
        samples on noisy volumes).
    pinhole_below : float
        ``init='genus0'``: close the solid's noise pinholes of samples below this many voxels (0 = never).
    """
    flipped = False
    facts: dict = {"kind": init if init_mesh is None else "mesh"}
    x = None
    if init_mesh is None and init == "genus0":
        x, faces, more = genus0_surface(volume, volume.values if values is None else values, join_below,
                                        pinhole_below)
        facts.update(more)
        if x is None:
            facts["kind"] = "auto"
            facts["fallback"] = "the genus-0 start failed (" + more["disambiguation"] + "): enclosing sphere"
    if x is not None:
        pass
    elif init_mesh is not None:
        x, faces, flipped = prepare_init_mesh(init_mesh)
    elif init in ("auto", "genus0"):
        x, faces, more = enclosing_sphere(volume, edge_length * volume.h, _INIT_MARGIN_VOXELS * volume.h)
        facts.update(more)
    else:
        x, faces = fibonacci_sphere(init_vertices, init_radius, 0.5 * (volume.lower + volume.upper))
    inside = volume.contains(x)
    if not inside.all():
        raise InputError(
            f"method 'shape_gradient': {int((~inside).sum())} of {len(x)} vertices of the initial surface "
            f"lie outside the volume box [{volume.lower.round(4).tolist()}, {volume.upper.round(4).tolist()}]"
            " — the volume must contain the initial surface (pass a smaller init_radius or init_mesh)")
    return x, faces, flipped, facts


#: sub-voxel offsets (in voxels) of the level set at which the digital topology is also read (see target_topology)
_TOPOLOGY_LEVELS = (0.0, -0.25, 0.25, -0.5, 0.5)


def _inside_box(values: np.ndarray, level: float) -> np.ndarray:
    """``values`` cut to the box of the samples below ``level`` plus one sample on every side (where there is
    one): every region below a lower level lies inside it, surrounded by samples above, so its components and
    Euler numbers are those of the whole grid — at a fraction of the cost (the sphere at N = 96: 1/10)."""
    below = values < level
    if not below.any():
        return values
    box = []
    for ax in range(values.ndim):
        hit = np.flatnonzero(below.any(axis=tuple(k for k in range(values.ndim) if k != ax)))
        box.append(slice(max(int(hit[0]) - 1, 0), min(int(hit[-1]) + 2, values.shape[ax])))
    return values[tuple(box)]


def target_topology(volume: Volume) -> dict:
    """What the region φ < 0 looks like at grid resolution, against one genus-0 surface.

    The digital topology of a sampled level set is ambiguous wherever features are thinner than a voxel (a thin
    sulcus or ear, two gyri closer than h): the counts change with the connectivity (6 or 26 neighbours) and
    with a shift of the level by a fraction of a voxel.  So the region is read at the levels
    φ < t·h, t ∈ {0, ±1/4, ±1/2}, with both connectivities (``skimage.measure.label`` for the components,
    ``skimage.measure.euler_number`` for χ of the solid = components − tunnels + cavities), and the target is
    *compatible with one genus-0 surface* when at least one reading gives one component with χ = 1.  A torus,
    two separate objects or an object with a cavity give no such reading; the bunny and the cortex at N = 96 do.

    Returns ``{"compatible": bool, "components": int, "euler_solid": int, "surface_euler": int,
    "readings": [...], "message": str}`` (counts of the plain reading: level 0, 26-connected foreground).
    """
    from skimage.measure import euler_number, label

    readings = []
    values = _inside_box(volume.values, max(_TOPOLOGY_LEVELS) * volume.h)
    for t in _TOPOLOGY_LEVELS:
        inside = values < t * volume.h
        for conn in (3, 1):
            n = int(label(inside, connectivity=conn, return_num=True)[1])
            chi = int(euler_number(inside, connectivity=conn))
            readings.append({"level_voxels": t, "connectivity": 26 if conn == 3 else 6, "components": n,
                             "euler_solid": chi})
    plain = readings[0]
    compatible = any(r["components"] == 1 and r["euler_solid"] == 1 for r in readings)
    out = {"compatible": compatible, "components": plain["components"], "euler_solid": plain["euler_solid"],
           "surface_euler": 2 * plain["euler_solid"], "readings": readings, "message": ""}
    if not compatible:
        n, chi = plain["components"], plain["euler_solid"]
        what = (f"{n} separate components" if n != 1 else
                f"one component with Euler characteristic {chi} (a genus-0 solid has 1: "
                f"{'handles or tunnels' if chi < 1 else 'cavities'})")
        out["message"] = (f"the region φ < 0 has {what} at grid resolution, but the method evolves one genus-0 "
                          "surface: the result cannot have the target's topology")
    return out


def topology_gap(topology: dict) -> int:
    """How far the region φ < 0 is from one genus-0 solid at its most favourable reading
    (:func:`target_topology`): min over readings of (components − 1) + |χ_solid − 1| — 0 when compatible, 1 for a
    torus, about the number of handles for a shell with openings."""
    return min(r["components"] - 1 + abs(r["euler_solid"] - 1) for r in topology["readings"])


def denoised_topology(volume: Volume, noise: float, noise_voxels: float = 0.1, least_sigma: float = 1.0) -> dict:
    """:func:`target_topology` of the volume Gaussian-smoothed by at least ``least_sigma`` voxels, more where its
    i.i.d. noise (std ``noise``, world units) would stay above ``noise_voxels`` of a voxel: additive noise makes
    speckle components and pinhole tunnels, and so does a mask's label noise (single flipped voxels, which a
    noise estimate does not see); openings a few voxels wide survive the smoothing."""
    from scipy.ndimage import gaussian_filter

    from .field import start_smoothing

    sigma = max(start_smoothing(noise / volume.h, noise_voxels), least_sigma)
    smooth = gaussian_filter(np.asarray(volume.values, float), sigma, mode="nearest")
    return target_topology(Volume(smooth, volume.origin, volume.spacing))


def genus0_surface(volume: Volume, values: np.ndarray, join_below: float = JOIN_BELOW_VOXELS,
                   pinhole_below: float = 0.0):
    """(vertices, faces, facts) of a genus-0 surface of the region ``values < 0`` (world coordinates, outward),
    or ``(None, None, facts)`` when no attempt gave one.

    Where the region falls apart into pieces at grid resolution (a part thinner than a voxel), the pieces whose lowest
    saddle of φ lies below ``join_below`` voxels are first joined through it
    (:func:`methods.shape_gradient.saddles.join_pieces`: the samples of a 6-connected path through each saddle of a
    spanning tree set to −:data:`JOIN_DEPTH_VOXELS` voxel); farther pieces stay apart and the growth keeps the largest
    group.  The region is grown from its deepest sample, in order of φ, keeping only simple points
    (:func:`methods.shape_gradient.digital.homotopic_growth`): a solid with one component, no handle and no cavity that
    takes every inside sample except where the sampled region has a handle (two sulcal banks closer than a voxel), where
    it stops at the thinnest place — unless that place is a noise pinhole: one sample below ``pinhole_below`` voxels
    closing the hole (:func:`methods.shape_gradient.pinholes.close_pinholes`).  Its marching-cubes surface
    (:func:`methods.shape_gradient.digital.ball_field`) is one closed genus-0 surface within a fraction of a voxel of φ
    = 0 elsewhere (a joining path: a tube about a voxel wide). Facts: samples inside / in the solid / left out (the path
    samples count in the solid, not as inside), how marching cubes' ambiguous cells were resolved, pieces of φ < 0,
    joins, their saddles (voxels), path samples, pinholes closed and their samples.
    """
    from .digital import ball_field, homotopic_growth
    from .pinholes import close_pinholes
    from .saddles import join_pieces

    values = np.asarray(values, dtype=np.float64)
    inside = values < 0
    core, joins = join_pieces(values[1:-1, 1:-1, 1:-1], 0.0, join_below * volume.h, JOIN_DEPTH_VOXELS * volume.h)
    if joins["joins"]:
        values = values.copy()
        values[1:-1, 1:-1, 1:-1] = core
    solid = homotopic_growth(values, 0.0)
    solid, pins = close_pinholes(values, solid, 0.0, pinhole_below * volume.h)
    facts = {"inside_samples": int(inside.sum()), "solid_samples": int(solid.sum()),
             "left_out_samples": int((inside & ~solid).sum()), "disambiguation": "failed",
             "pieces": joins["pieces"], "joined_pieces": joins["joins"],
             "join_saddles_voxels": [round(w / volume.h, 3) for w in joins["join_saddles"]],
             "join_samples": joins["join_samples"], "pinholes": pins["pinholes"],
             "pinhole_samples": pins["pinhole_samples"]}
    if not solid.any():
        raise InputError("method 'shape_gradient': no sample of the volume is inside (φ < 0) away from the box's "
                         "outer layer — there is no surface to reconstruct")
    _, mesh, how = ball_field(values, solid, volume.h)
    facts["disambiguation"] = how
    if mesh is None:
        return None, None, facts
    v_idx, faces = mesh
    x = volume.index_to_world(v_idx)
    cross = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
    if float(np.einsum("ij,ij->i", x[faces[:, 0]], cross).sum()) < 0:
        faces = faces[:, ::-1]
    facts["vertices"] = int(len(x))
    return x, np.ascontiguousarray(faces), facts


def enclosing_sphere(volume: Volume, edge_length: float, margin: float) -> tuple[np.ndarray, np.ndarray, dict]:
    """A Fibonacci sphere around the region φ < 0, meshed at about ``edge_length`` (world units).

    Centre: the middle of the bounding box of the inside grid points; radius: their largest distance from it
    plus ``margin``, reduced where needed to stay a voxel inside the grid box.  Returns (vertices, faces,
    facts) — facts hold the centre, radius and whether it had to be shrunk.
    """
    inside = np.argwhere(volume.values < 0)
    pts = volume.index_to_world(inside)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = float(np.linalg.norm(pts - center, axis=1).max()) + margin
    room = float(min((center - volume.lower).min(), (volume.upper - center).min())) - volume.h
    shrunk = radius > room
    radius = max(min(radius, room), volume.h)
    area = 4.0 * np.pi * radius ** 2
    n = int(max(12, round(area / (np.sqrt(3.0) / 4.0 * edge_length ** 2) / 2.0)))
    x, f = fibonacci_sphere(n, radius, center)
    return x, f, {"center": center.tolist(), "radius": radius, "shrunk_to_grid": bool(shrunk), "vertices": n}
