"""``python -m bench phantoms`` / ``volume`` / ``info``: list phantoms, write a phantom volume, describe a file."""

from __future__ import annotations

from phantoms import (NOISE_KINDS, PHANTOMS, VARIANTS, InputError, add_noise, check_volume_output, get_phantom,
                      load_volume, save_volume)
from phantoms.user import parse_spec

from ..terminal import printable
from .validators import finite_float


def _cmd_phantoms(args) -> int:
    print(f"{'name':<15} {'genus':>5} {'creases':>7} {'paper SNR':>9}  parameters / description")
    for name, cls in PHANTOMS.items():
        ph = cls()
        snr = "-" if ph.paper_snr_db is None else f"{ph.paper_snr_db:g} dB"
        params = ", ".join(f"{k}={v}" for k, v in ph.params.items())
        print(f"{name:<15} {ph.genus:>5} {str(ph.has_creases).lower():>7} {snr:>9}  {params}")
        print(f"{'':<40}{ph.description}")
    from phantoms.anatomy import ANATOMY  # anatomy shapes: listed from class facts, not built

    for name, cls in ANATOMY.items():
        print(f"{name:<15} {cls.genus:>5} {str(cls.has_creases).lower():>7} {'-':>9}  {cls.shape_kind}; "
              f"options: {'&'.join(f'{k}=' for k in cls.parameter_names)}")
        print(f"{'':<40}{cls.description}")
    from phantoms.real import REAL_SHAPES  # real shapes: listed from class facts, not loaded
    from phantoms.real_tier import FINE_SHAPES

    for name, cls in {**REAL_SHAPES, **FINE_SHAPES}.items():
        print(f"{name:<15} {cls.genus:>5} {str(cls.has_creases).lower():>7} {'-':>9}  data: {cls.data}")
        print(f"{'':<40}{cls.description}")
    blank = f"{'':>5} {'':>7} {'-':>9}"
    print(f"{'mesh:PATH':<15} {blank}  any closed triangle mesh file trimesh reads (OBJ, PLY, STL, OFF, ...)")
    print(f"{'volume:PATH':<15} {blank}  your volume: NIfTI, NRRD, MetaImage, DICOM folder, .npz/.npy; "
          "?threshold=T, label=L, truth=FILE, ... (docs/PHANTOMS.md)")
    print(f"{'':<40}a glob in PATH (mesh:shapes/*.obj) is one phantom per file")
    print(f"\nvariants: {', '.join(VARIANTS)} (default sdf); grid: N³ points over [-2.5, 2.5]³ (default N = 96)")
    return 0


def _cmd_volume(args) -> int:
    ph = get_phantom(args.phantom)
    check_volume_output(args.output)  # a bad output path fails before the volume is computed
    vol = ph.volume(n=args.n, extent=args.extent, variant=args.variant)
    snr = args.snr
    if args.noise != "none" and snr is None:
        snr = ph.paper_snr_db
        if snr is None:
            raise InputError(f"--snr is required for phantom {args.phantom!r} (no paper SNR)")
    vol, achieved = add_noise(vol, args.noise, snr, seed=args.seed)
    path = save_volume(args.output, vol)
    print(printable(f"wrote {path}: {args.phantom} ({args.variant}), grid {'×'.join(map(str, vol.shape))}, "
                    f"spacing {vol.h:.6g}"))
    if args.noise == "none":
        print("noise: none")
    else:
        print(f"noise: {args.noise}, seed {args.seed}, SNR requested {snr:.3f} dB, achieved {achieved:.3f} dB")
    return 0


def _cmd_info(args) -> int:
    spec = str(args.file)
    if spec.startswith("volume:") and "labels" in parse_spec(spec)[1]:
        from phantoms.labels import expand_labels

        phantoms = expand_labels(spec, spec)          # reads the labels; an absent one is refused naming those present
        print(printable(f"file:         {spec}"))
        print(printable(f"labels:       {len(phantoms)} phantom(s): {', '.join(n for n, _ in phantoms)}"))
        for name, source in phantoms:
            print(printable(f"\n{name} ({source}):"))
            _describe(source, args.mask, indent="  ")
        return 0
    print(printable(f"file:         {spec}"))           # a file name can hold ESC: shown, not obeyed
    _describe(spec, args.mask)
    return 0


def _describe(spec: str, mask: bool, indent: str = "") -> None:
    """The shape, origin, spacing, value range and closedness of one volume (a file or a ``volume:`` spec)."""
    vol = load_volume(spec, mask=True if mask else None)
    s = vol.summary()
    lines = [f"shape:        {s['shape']}",
             f"origin:       {[float(f'{v:.6g}') for v in s['origin']]}",    # 6 digits, not 6 decimals: 1e-9 m
             f"spacing:      {[float(f'{v:.6g}') for v in s['spacing']]}",
             f"value range:  [{s['min']:.6g}, {s['max']:.6g}]",
             f"zero crossing: {'yes' if s['zero_crossing'] else 'no'}"]
    if not s["zero_crossing"]:
        lines.append("closed:       no (the volume has no zero level set)")
    elif s["closed"]:
        lines.append("closed:       yes (no zero crossing on the boundary faces of the grid)")
    else:
        lines.append("closed:       no (the zero level set reaches the boundary of the grid)")
    if spec.startswith("volume:") and "truth" in parse_spec(spec)[1]:
        ph = get_phantom(spec)          # reads the truth and checks it lies on the volume's surface
        lines.append(f"truth:        {ph.truth_note} (on the volume's zero level set)")
    for line in lines:
        print(printable(indent + line))


def register(sub) -> None:
    p = sub.add_parser("phantoms", help="list the phantoms and their parameters",
                       description="List the built-in phantoms, their parameters and the paper's SNR.")
    p.set_defaults(func=_cmd_phantoms)

    p = sub.add_parser("volume", help="write a phantom volume (.npz)",
                       description="Sample a phantom on an N³ grid, optionally add seeded noise, write .npz "
                                   "(keys values, origin, spacing) and print the achieved SNR.")
    p.add_argument("phantom", help=f"one of: {', '.join(PHANTOMS)}, a real shape, mesh:PATH or volume:PATH")
    p.add_argument("--n", type=int, default=96, help="grid points per axis (>= 8; default 96)")
    p.add_argument("--extent", type=finite_float, default=2.5, help="grid covers [-E, E]³ (default 2.5)")
    p.add_argument("--variant", choices=VARIANTS, default="sdf", help="sdf (exact distance) or paper polynomial")
    p.add_argument("--noise", choices=NOISE_KINDS, default="none", help="noise kind (default none)")
    p.add_argument("--snr", type=finite_float, default=None,
                   help="requested SNR in dB (default: the paper's SNR for the phantom)")
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("-o", "--output", required=True, help="output .npz file")
    p.set_defaults(func=_cmd_volume)

    p = sub.add_parser("info", help="describe a volume file",
                       description="Read a volume (.npz, .npy, NIfTI, NRRD, MetaImage, a DICOM series folder, or "
                                   "a volume:PATH?options spec; two-valued masks become signed distance volumes) "
                                   "and print its shape, origin, spacing (RAS+ world coordinates), value range "
                                   "and whether its zero level set is closed inside the grid.")
    p.add_argument("file", help="a volume file, a DICOM folder or volume:PATH[?threshold=T&label=L&...]")
    p.add_argument("--mask", action="store_true", help="require the file to be a binary mask")
    p.set_defaults(func=_cmd_info)
