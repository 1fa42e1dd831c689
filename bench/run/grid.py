"""A run config → its cells (:class:`~bench.run.contracts.Cell`), each with a stable, readable ``cell_id``.

A cell is everything needed to compute one result from nothing: phantom, variant, N, extent, noise kind,
requested SNR, seed, method, label, the method's parameters (phantom-specific ones applied), the number of
metric samples and the plug-in modules to import.  Executors ship cells to workers as they are (they pickle).

A plug-in method's cells also carry ``method_code``, the fingerprint of its code
(:func:`bench.run.method_code.method_fingerprint`).  It is not part of the ``cell_id``: the cell record keeps it, and
``--resume`` reruns (and overwrites) a finished cell whose plug-in changed since.  Built-in methods have none:
the suite's code identity covers them.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import replace
from typing import Any

from phantoms import VOLUME_PREFIX, InputError, expand_phantoms
from phantoms.user import parse_spec

from .contracts import Cell

__all__ = ["as_cell", "canonical_json", "cell_id", "expand_grid", "slug"]


def slug(text: str) -> str:
    """``text`` reduced to characters safe in a file name."""
    return re.sub(r"[^A-Za-z0-9.=+-]+", "_", str(text)).strip("_") or "x"


def canonical_json(obj: Any) -> str:
    """Compact JSON with sorted keys: the same parameters always give the same text (and hash)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=repr)


def cell_id(cell: Cell | dict) -> str:
    """A readable, stable identifier:
    ``<phantom>_<variant>_n<N>[_<degradation>]_<noise>[<snr>dB]_s<seed>_<label>_<hash>``.

    The hash covers every parameter of the cell, so sweeps and changed settings never collide.

    Parameters
    ----------
    cell : Cell or dict
        A cell, or its dict form (:meth:`Cell.to_dict`, which is what the hash covers).

    Returns
    -------
    str
    """
    if isinstance(cell, Cell):
        cell = cell.to_dict()
    key = {k: cell[k] for k in ("phantom", "variant", "n", "extent", "noise", "snr_requested", "seed",
                                "method", "params", "n_samples")}
    if cell.get("source", cell["phantom"]) != cell["phantom"]:
        key["source"] = cell["source"]
    if cell.get("input"):
        key["input"] = cell["input"]
    if cell.get("degrade"):
        key["degrade"] = cell["degrade"]
    digest = hashlib.sha1(canonical_json(key).encode()).hexdigest()[:8]
    noise = cell["noise"] if cell["noise"] == "none" else f"{cell['noise']}{cell['snr_requested']:g}dB"
    degrade = [slug(cell["degrade"])] if cell.get("degrade") else []
    return "_".join([slug(cell["phantom"]), cell["variant"], f"n{cell['n']}", *degrade, slug(noise),
                     f"s{cell['seed']}", slug(cell["label"]), digest])


def as_cell(cell: Cell | dict) -> Cell:
    """``cell`` as a :class:`Cell`: the stages' public functions accept a cell's dict form too (tests, plug-ins,
    records read back from disk); a dict without ``cell_id`` gets the one :func:`cell_id` gives it.

    Parameters
    ----------
    cell : Cell or dict
        A cell or its dict form (:meth:`Cell.from_dict`).

    Returns
    -------
    Cell
    """
    if isinstance(cell, Cell):
        return cell
    out = Cell.from_dict(cell)
    return out if out.cell_id else replace(out, cell_id=cell_id(out))


def input_fingerprint(source: str) -> str | None:
    """For a ``mesh:`` / ``volume:`` phantom, a hash of its files' sizes and modification times (the image, a DICOM
    folder's files, a ``truth=`` file): part of the cell's identity, so ``--resume`` after the data changed
    computes the cells anew instead of keeping results computed from the file as it was.  None for a built-in
    phantom."""
    from pathlib import Path

    from phantoms import is_file_phantom, phantom_path

    if not is_file_phantom(source):
        return None
    paths = [Path(phantom_path(source)).expanduser()]
    if source.startswith(VOLUME_PREFIX) and "truth" in parse_spec(source)[1]:
        paths.append(Path(parse_spec(source)[1]["truth"]).expanduser())
    stamps = []
    for p in paths:
        files = sorted(p.iterdir()) if p.is_dir() else [p]
        for f in files:
            try:
                st = f.stat()
                stamps.append((str(f.resolve()), st.st_size, st.st_mtime_ns))
            except OSError:
                stamps.append((str(f), None, None))
    return hashlib.sha1(canonical_json(stamps).encode()).hexdigest()[:12]


def grid_sizes(source: str, sizes) -> list[int]:
    """The grid sizes N a phantom runs at: a user volume runs on its native grid (N = 0 here; the row gets its
    largest dimension) unless its spec says ``resample=yes``; so does a real-tier phantom (its own fine grid,
    coarsened by its degradations)."""
    from phantoms.real_tier import FINE_SHAPES

    if source in FINE_SHAPES:
        return [0]
    if source.startswith(VOLUME_PREFIX) and not parse_spec(source)[1].get("resample"):
        return [0]
    return list(sizes)


def method_codes(names) -> dict[str, dict | None]:
    """``{method name: fingerprint}`` of the methods named (None: a built-in, or a name no longer registered)."""
    from methods import available_methods

    from .method_code import method_fingerprint

    registry = available_methods()
    return {name: (method_fingerprint(registry[name]) if name in registry else None) for name in names}


def _inputs(cfg):
    """(index, noise setting, degradation) of the grid's inputs: each noise setting undegraded, then each
    degradation without noise (a degradation is the input's own error model; noise is not added to it)."""
    degrades = [d for d in cfg.degrade if d != "none"]
    plain_too = "none" in cfg.degrade
    out = [(k, noise, "none") for k, noise in enumerate(cfg.noise)] if plain_too else []
    none = next((s for s in cfg.noise if s.kind == "none"), None)
    none = none or replace(cfg.noise[0], kind="none", snr=None)
    out += [(0, none, d) for d in degrades]
    return out


def _seeds(seeds, noise_kind: str, degrade: str) -> list:
    """The seeds a cell runs at: every seed with noise or label noise, else the first (nothing else is random
    but the metric sampling)."""
    return list(seeds) if noise_kind != "none" or "label_noise" in degrade else list(seeds[:1])


def expand_grid(cfg) -> list[Cell]:
    """All cells of a run config, in order phantom → variant → N → noise → seed → method.

    A ``mesh:`` / ``volume:`` glob is one phantom per file (:func:`phantoms.expand_phantoms`; the cell's
    ``source`` is the file's spec, its ``phantom`` the file's stem).  Clean cells (noise ``none``) are run for
    the first seed only: without noise the seed changes nothing but the metric sampling.  With
    ``grid.vary = "one_at_a_time"`` only the (N, noise) pairs that keep one of them at its first value are run:
    every noise setting at the first N, every N with the first noise setting.

    Parameters
    ----------
    cfg : bench.config.RunConfig
        A validated config.

    Returns
    -------
    list of Cell
        The cells, each with its ``cell_id`` (:func:`cell_id` of its dict form).

    Raises
    ------
    InputError
        An empty phantom glob or two phantoms of the same name (:func:`phantoms.expand_phantoms`), or
        duplicate cells.
    """
    cells = []
    one = cfg.vary == "one_at_a_time"
    codes = method_codes(dict.fromkeys(spec.name for spec in cfg.methods))
    for phantom, source in expand_phantoms(cfg.phantoms):
        fingerprint = input_fingerprint(source)
        for variant in cfg.variants:
            for n in grid_sizes(source, cfg.n):
                for k, noise, degrade in _inputs(cfg):
                    if one and n != cfg.n[0] and k != 0:
                        continue
                    snr = noise.snr_for(source)
                    for seed in _seeds(cfg.seeds, noise.kind, degrade):
                        for spec in cfg.methods:
                            if not spec.runs_on(noise.kind):
                                continue
                            for label, params in spec.instances():
                                cell = {
                                    "phantom": phantom, **({"source": source} if source != phantom else {}),
                                    **({"input": fingerprint} if fingerprint else {}),
                                    **({"degrade": degrade} if degrade != "none" else {}),
                                    "variant": variant, "n": int(n),
                                    "extent": float(cfg.extent), "noise": noise.kind,
                                    "snr_requested": snr, "seed": int(seed), "method": spec.name,
                                    "label": label, "params": spec.params_for(params, phantom),
                                    "n_samples": int(cfg.n_samples), "imports": list(cfg.imports),
                                    **({"method_code": codes[spec.name]} if codes[spec.name] else {}),
                                }
                                cell["cell_id"] = cell_id(cell)
                                cells.append(Cell.from_dict(cell))
    ids = [c.cell_id for c in cells]
    if len(set(ids)) != len(ids):  # label uniqueness is checked when the config is validated
        raise InputError("the grid has duplicate cells (the same method settings listed twice)")
    return cells
