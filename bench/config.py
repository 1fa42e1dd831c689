"""Run configurations: what grid ``python -m bench run`` computes.

A configuration is a TOML file (read with :mod:`tomllib`)::

    name = "paper"
    description = "..."
    [grid]
    phantoms = ["sphere", "ellipsoid"]      # `python -m bench phantoms`, "mesh:PATH", "volume:PATH?threshold=3"
                                            # or { volume = "PATH", threshold = 3 }; a glob: one per file
    variants = ["sdf"]                      # sdf | paper
    n = 96                                  # grid points per axis; a number or a list
    extent = 2.5                            # the grid covers [-extent, extent]^3
    seeds = [0]                             # noise (and metric sampling) seeds
    vary = "all"                            # or "one_at_a_time": noise list at n[0], n list at noise[0]
    noise = [                               # kind none | gaussian | uniform;
      { kind = "none" },                    # snr = "paper" (the phantom's paper SNR), a number
      { kind = "gaussian", snr = "paper" }, # or a list of numbers (dB)
    ]
    degrade = ["none", "mask", "thick_slices@3+partial_volume"]   # optional (docs/PHANTOMS.md, "Degradations")

    [[methods]]
    name = "shape_gradient"                 # a registered method (`python -m bench methods`)
    label = "shape_gradient"                # optional, unique; default: the name
    params = { alpha = 5.0, beta = 1.0 }    # fixed parameters
    sweep = { beta = [0.0, 1.0] }           # optional: one cell per combination (Cartesian product)
    noise = ["none"]                        # optional: the noise kinds it runs on (default: every one)
    [methods.phantom_params.fused_spheres]  # optional: parameters for one phantom only
    max_iter = 150
    [metrics]
    n_samples = 100000                      # surface samples per direction for the distances
    [run]
    timeout = 3600                          # seconds per cell (0 or absent: none)
    method_timeout = 600                    # seconds for method.reconstruct alone; score_timeout: for scoring
    memory_limit = 8                        # GB of address space per cell (0: none; absent: 75 % of RAM / jobs)
    force = false                           # true: run cells whose cost estimate exceeds their time limit
    imports = ["my_package.my_methods"]     # modules imported first (e.g. to register_method plug-ins)
    [report]                                # optional: paper_columns = [{ title, label, noise }, ...] (the
    uniform_label = "shape_gradient"        # paper-style tables: a column per entry), the uniform-noise label(s)

Everything is validated before any work starts (:func:`RunConfig.validate`): unknown keys, phantoms, ..., bad
parameters and grids over :data:`MAX_CELLS` raise :class:`phantoms.InputError` (one line, exit code 2).
"""

from __future__ import annotations

import copy
import itertools
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from phantoms import (NOISE_KINDS, VARIANTS, InputError, expand_phantoms, get_phantom, is_file_phantom,
                      is_phantom_name, phantom_names, short_name)
from phantoms.registry import check_phantom_files
from phantoms.user import check_truth_frame, spec_from_table

from .run.estimate import check_force
from .run.limits import check_gb, check_seconds
from .textspec import read_toml

__all__ = ["NoiseSpec", "MethodSpec", "RunConfig", "load_config", "config_from_dict", "builtin_config",
           "parse_noise_spec", "parse_degrade_list", "BUILTIN_CONFIGS"]

#: where the shipped configurations live (package data)
CONFIG_DIR = Path(__file__).resolve().parent / "configs"
#: shipped configurations (``bench/configs/<name>.toml``)
BUILTIN_CONFIGS = ("paper", "quick")

#: the most cells one run takes (a grid beyond it is refused before it is expanded)
MAX_CELLS = 100_000
_TOP_KEYS = {"name", "description", "grid", "methods", "metrics", "run", "report"}
_GRID_KEYS = {"phantoms", "variants", "n", "extent", "seeds", "noise", "vary", "degrade"}
#: grid.vary: "all" (the full product) or "one_at_a_time" (the noise list at the first N, the N list at the first
#: noise setting — a robustness sweep without the product's cost)
VARY = ("all", "one_at_a_time")
_NOISE_KEYS = {"kind", "snr"}
_METHOD_KEYS = {"name", "label", "params", "sweep", "phantom_params", "noise"}
_METRICS_KEYS = {"n_samples"}
_RUN_KEYS = {"timeout", "method_timeout", "score_timeout", "memory_limit", "imports", "force"}
_REPORT_KEYS = {"paper_columns", "uniform_label"}
_COLUMN_KEYS = {"title", "label", "noise"}


def _check_keys(table: Any, allowed: set[str], where: str) -> dict:
    if not isinstance(table, dict):
        raise InputError(f"{where}: expected a table, got {type(table).__name__}")
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise InputError(f"{where}: unknown key {unknown[0]!r}; valid keys: {', '.join(sorted(allowed))}")
    return table


def _as_list(value: Any, where: str) -> list:
    if isinstance(value, list) and not value:
        raise InputError(f"{where}: must not be empty")
    return value if isinstance(value, list) else [value]


def _int(value: Any, where: str, minimum: int | None = None) -> int:
    if (isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value))
            or float(value) != int(value)):
        raise InputError(f"{where}: expected an integer, got {value!r}")
    value = int(value)
    if minimum is not None and value < minimum:
        raise InputError(f"{where}: must be >= {minimum}, got {value}")
    return value


def _float(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise InputError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class NoiseSpec:
    """One noise setting: ``kind`` and requested SNR (``"paper"``, a number in dB, or None for none)."""

    kind: str
    snr: float | str | None = None

    def snr_for(self, phantom: str) -> float | None:
        """The requested SNR in dB for ``phantom`` (None for kind none)."""
        if self.kind == "none":
            return None
        if self.snr == "paper":
            snr = None if is_file_phantom(phantom) else get_phantom(phantom).paper_snr_db
            if snr is None:
                raise InputError(f"noise {self.kind!r} with snr = 'paper': phantom {phantom!r} has no paper SNR;"
                                 " give the SNR in dB (e.g. --noise none,gaussian@30)")
            return float(snr)
        return float(self.snr)

    def to_dict(self) -> dict:
        return {"kind": self.kind} if self.kind == "none" else {"kind": self.kind, "snr": self.snr}


@dataclass
class MethodSpec:
    """A method entry of the grid; expands to one or more method instances (parameter sweeps)."""

    name: str
    label: str
    params: dict = field(default_factory=dict)
    sweep: dict = field(default_factory=dict)
    phantom_params: dict = field(default_factory=dict)
    noise: tuple = ()          # the noise kinds this method runs on; empty: every kind of the grid

    def runs_on(self, kind: str) -> bool:
        return not self.noise or kind in self.noise

    def instances(self) -> list[tuple[str, dict]]:
        """``[(label, params), ...]``: one per sweep combination (label gets ``[k=v,...]``)."""
        if not self.sweep:
            return [(self.label, dict(self.params))]
        keys = list(self.sweep)
        out = []
        for combo in itertools.product(*(self.sweep[k] for k in keys)):
            params = dict(self.params)
            params.update(zip(keys, combo))
            tag = ",".join(f"{k}={_fmt_value(v)}" for k, v in zip(keys, combo))
            out.append((f"{self.label}[{tag}]", params))
        return out

    def params_for(self, params: dict, phantom: str) -> dict:
        """One phantom's cell parameters: its phantom_params applied, ``{phantom}`` → :func:`phantoms.short_name`."""
        out, shown = {**params, **self.phantom_params.get(phantom, {})}, short_name(phantom)
        return {k: v.replace("{phantom}", shown) if isinstance(v, str) else v for k, v in out.items()}

    def to_dict(self) -> dict:
        d: dict = {"name": self.name, "label": self.label, "params": copy.deepcopy(self.params)}
        if self.sweep:
            d["sweep"] = copy.deepcopy(self.sweep)
        if self.phantom_params:
            d["phantom_params"] = copy.deepcopy(self.phantom_params)
        if self.noise:
            d["noise"] = list(self.noise)
        return d


def _fmt_value(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


@dataclass
class RunConfig:
    """A validated grid description (see the module docstring for the TOML layout)."""

    name: str = "custom"
    description: str = ""
    phantoms: list[str] = field(default_factory=list)
    variants: list[str] = field(default_factory=lambda: ["sdf"])
    n: list[int] = field(default_factory=lambda: [96])
    extent: float = 2.5
    seeds: list[int] = field(default_factory=lambda: [0])
    noise: list[NoiseSpec] = field(default_factory=lambda: [NoiseSpec("none")])
    degrade: list[str] = field(default_factory=lambda: ["none"])    # canonical degradation texts
    vary: str = "all"
    methods: list[MethodSpec] = field(default_factory=list)
    n_samples: int = 100_000
    timeout: float | None = None
    method_timeout: float | None = None
    score_timeout: float | None = None
    memory_limit: float | None = None      # GB per cell; None: the default (bench.run.limits), 0: no limit
    force: bool = False                    # run cells over their estimated time (bench.run.estimate)
    imports: list[str] = field(default_factory=list)
    report: dict = field(default_factory=dict)
    source: str = ""

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict:
        """A TOML/JSON-able dict that :func:`config_from_dict` reads back to the same config."""
        d = {
            "name": self.name,
            "description": self.description,
            "grid": {
                "phantoms": list(self.phantoms), "variants": list(self.variants), "n": list(self.n),
                "extent": self.extent, "seeds": list(self.seeds),
                "noise": [s.to_dict() for s in self.noise], **({"vary": self.vary} if self.vary != "all" else {}),
                **({"degrade": list(self.degrade)} if self.degrade != ["none"] else {}),
            },
            "methods": [m.to_dict() for m in self.methods],
            "metrics": {"n_samples": self.n_samples},
            "run": {"timeout": self.timeout or 0, "imports": list(self.imports)},
        }
        d["run"].update({k: getattr(self, k) for k in ("method_timeout", "score_timeout") if getattr(self, k)})
        d["run"].update({} if self.memory_limit is None else {"memory_limit": self.memory_limit})
        d["run"].update({"force": True} if self.force else {})
        if self.report:
            d["report"] = copy.deepcopy(self.report)
        return d

    # ------------------------------------------------------------------ validation
    def check_size(self, n_phantoms: int) -> None:
        """Refuse a grid of more than :data:`MAX_CELLS` cells (an upper bound counted without expanding it)."""
        inputs = len(self.noise) * ("none" in self.degrade) + len([d for d in self.degrade if d != "none"])
        bound = n_phantoms * len(self.variants) * len(self.n) * inputs * len(self.seeds) * sum(
            math.prod(len(v) for v in m.sweep.values()) for m in self.methods)
        if bound > MAX_CELLS:
            raise InputError(f"the grid has up to {bound:.3g} cells; at most {MAX_CELLS:,} are run at once: split it")
    def import_plugins(self) -> None:
        """Import the ``run.imports`` modules (which may register methods); InputError if one fails."""
        from methods import import_plugins

        from .imports import probe_imports

        try:
            probe_imports(self.imports)         # one that ends its process at import: named, not a silent exit
            import_plugins(self.imports)
        except InputError as exc:
            raise InputError(f"run.imports: {exc}") from None

    def validate(self) -> None:
        """Check everything against the registries (phantoms, methods, parameters); InputError on failure."""
        from methods import available_methods, get_method

        if not self.phantoms:
            raise InputError("grid.phantoms: no phantoms to run")
        if not self.methods:
            raise InputError("methods: no methods to run")
        known = phantom_names()
        for p in self.phantoms:
            if not is_phantom_name(p):
                raise InputError(f"unknown phantom {p!r}; valid phantoms: {', '.join(known)}, mesh:PATH or "
                                 "volume:PATH")
        if len(set(self.phantoms)) != len(self.phantoms):
            raise InputError("grid.phantoms: a phantom is listed twice")
        expanded = expand_phantoms(self.phantoms)       # globs: an empty one is an error naming the pattern
        for _, source in expanded:
            check_phantom_files(source)       # missing files; one that cannot be read is a failed row instead
            check_truth_frame(source)         # a truth in another frame: refused before any cell, not per cell
        known = known + [name for name, _ in expanded]
        for v in self.variants:
            if v not in VARIANTS:
                raise InputError(f"unknown variant {v!r}; valid variants: {', '.join(VARIANTS)}")
        for n in self.n:
            if n < 8:
                raise InputError(f"grid.n: must be >= 8, got {n}")
        if not self.extent > 0:
            raise InputError(f"grid.extent: must be positive, got {self.extent}")
        for s in self.noise:
            for _, p in expanded:
                s.snr_for(p)
        self.check_size(len(expanded))
        if self.n_samples < 1000:
            raise InputError(f"metrics.n_samples: must be >= 1000, got {self.n_samples}")
        self.import_plugins()
        registry = available_methods()
        labels: dict[str, str] = {}
        for spec in self.methods:
            if spec.name not in registry:
                raise InputError(f"unknown method {spec.name!r}; valid methods: {', '.join(registry)}")
            for ph in spec.phantom_params:
                if ph not in known:
                    raise InputError(f"method {spec.label!r}: phantom_params for unknown phantom {ph!r}; "
                                     f"valid phantoms: {', '.join(known)}")
            for label, params in spec.instances():
                if label in labels:
                    raise InputError(f"method label {label!r} is used twice; give each [[methods]] entry a "
                                     "distinct label")
                labels[label] = spec.name
                for ph, _ in expanded:
                    get_method(spec.name, **spec.params_for(params, ph))  # raises InputError on bad params
        for i, col in enumerate(self.report.get("paper_columns", [])):
            if col["label"] not in labels:
                raise InputError(f"report.paper_columns[{i}]: label {col['label']!r} is not a method label of "
                                 f"this config; labels: {', '.join(labels)}")
        uniform = self.report.get("uniform_label")
        for u in ([uniform] if isinstance(uniform, str) else uniform or []):
            if u not in labels:
                raise InputError(f"report.uniform_label: {u!r} is not a method label of this config; "
                                 f"labels: {', '.join(labels)}")


# ---------------------------------------------------------------------- parsing
def config_from_dict(data: dict, source: str = "") -> RunConfig:
    """Build a :class:`RunConfig` from a parsed TOML dict (structure checked, registries not yet)."""
    where = source or "config"
    _check_keys(data, _TOP_KEYS, where)
    grid = _check_keys(data.get("grid", {}), _GRID_KEYS, f"{where}: [grid]")
    cfg = RunConfig(source=source)
    if "name" in data:
        if not isinstance(data["name"], str):
            raise InputError(f"{where}: name must be a string")
        cfg.name = data["name"]
    if "description" in data:
        cfg.description = str(data["description"])
    if "phantoms" not in grid:
        raise InputError(f"{where}: [grid] needs phantoms = [...]")
    cfg.phantoms = [spec_from_table(p, f"grid.phantoms[{i}]") if isinstance(p, dict) else str(p)
                    for i, p in enumerate(_as_list(grid["phantoms"], "grid.phantoms"))]
    if "variants" in grid:
        cfg.variants = [str(v) for v in _as_list(grid["variants"], "grid.variants")]
    if "n" in grid:
        cfg.n = [_int(v, "grid.n", 8) for v in _as_list(grid["n"], "grid.n")]
    if "extent" in grid:
        cfg.extent = _float(grid["extent"], "grid.extent")
    if grid.get("vary", "all") not in VARY:
        raise InputError(f"grid.vary: {grid['vary']!r} is not one of {', '.join(VARY)}")
    cfg.vary = grid.get("vary", "all")
    if "seeds" in grid:
        cfg.seeds = [_int(v, "grid.seeds", 0) for v in _as_list(grid["seeds"], "grid.seeds")]
    if "noise" in grid:
        cfg.noise = []
        for i, item in enumerate(_as_list(grid["noise"], "grid.noise")):
            if isinstance(item, str):
                cfg.noise.extend(parse_noise_spec(item))
                continue
            item = _check_keys(item, _NOISE_KEYS, f"grid.noise[{i}]")
            cfg.noise.extend(_noise_from(item.get("kind"), item.get("snr", "paper"), f"grid.noise[{i}]"))
    if "degrade" in grid:
        cfg.degrade = parse_degrade_list(_as_list(grid["degrade"], "grid.degrade"), "grid.degrade")
    methods = data.get("methods", [])
    if not isinstance(methods, list):
        raise InputError(f"{where}: methods must be an array of tables ([[methods]])")
    for i, m in enumerate(methods):
        cfg.methods.append(_method_from(m, f"methods[{i}]"))
    metrics = _check_keys(data.get("metrics", {}), _METRICS_KEYS, f"{where}: [metrics]")
    if "n_samples" in metrics:
        cfg.n_samples = _int(metrics["n_samples"], "metrics.n_samples", 1000)
    run = _check_keys(data.get("run", {}), _RUN_KEYS, f"{where}: [run]")
    for key in ("timeout", "method_timeout", "score_timeout"):
        if key in run:
            t = _float(run[key], f"run.{key}")
            if t < 0:
                raise InputError(f"run.{key}: must be >= 0 (0 = no timeout)")
            setattr(cfg, key, check_seconds(t, f"run.{key}") or None)
    cfg.memory_limit = check_gb(run.get("memory_limit"), "run.memory_limit")
    cfg.force = check_force(run.get("force", False))
    if "imports" in run:
        imports = run["imports"]
        if not isinstance(imports, list) or not all(isinstance(s, str) for s in imports):
            raise InputError("run.imports: expected a list of module names")
        cfg.imports = list(imports)
    cfg.report = _report_from(data.get("report", {}), f"{where}: [report]")
    return cfg


def _report_from(table: Any, where: str) -> dict:
    """The optional [report] table: paper_columns (title, label, noise kind) and uniform_label."""
    table = _check_keys(table, _REPORT_KEYS, where)
    out: dict = {}
    if "paper_columns" in table:
        cols = table["paper_columns"]
        if not isinstance(cols, list):
            raise InputError("report.paper_columns: expected a list of tables {title, label, noise}")
        out["paper_columns"] = []
        for i, col in enumerate(cols):
            col = _check_keys(col, _COLUMN_KEYS, f"report.paper_columns[{i}]")
            if not all(isinstance(col.get(k), str) for k in ("title", "label")):
                raise InputError(f"report.paper_columns[{i}]: title and label must be strings")
            noise = col.get("noise", "none")
            if noise not in NOISE_KINDS:
                raise InputError(f"report.paper_columns[{i}]: unknown noise kind {noise!r}; valid kinds: "
                                 f"{', '.join(NOISE_KINDS)}")
            out["paper_columns"].append({"title": col["title"], "label": col["label"], "noise": noise})
    if "uniform_label" in table:
        u = table["uniform_label"]
        if not (isinstance(u, str) or (isinstance(u, list) and u and all(isinstance(x, str) for x in u))):
            raise InputError("report.uniform_label: expected a method label (a string) or a list of them")
        out["uniform_label"] = table["uniform_label"]
    return out


def _noise_from(kind: Any, snr: Any, where: str) -> list[NoiseSpec]:
    if kind not in NOISE_KINDS:
        raise InputError(f"{where}: unknown noise kind {kind!r}; valid kinds: {', '.join(NOISE_KINDS)}")
    if kind == "none":
        return [NoiseSpec("none")]
    return [NoiseSpec(kind, "paper" if s == "paper" else _float(s, f"{where}.snr (a number in dB or 'paper')"))
            for s in _as_list(snr, f"{where}.snr")]


def _method_from(m: Any, where: str) -> MethodSpec:
    m = _check_keys(m, _METHOD_KEYS, where)
    name = m.get("name")
    if not isinstance(name, str) or not name:
        raise InputError(f"{where}: needs name = \"<method>\"")
    label = m.get("label", name)
    if not isinstance(label, str) or not label:
        raise InputError(f"{where}: label must be a non-empty string")
    params = m.get("params", {})
    if not isinstance(params, dict):
        raise InputError(f"{where}.params: expected a table")
    sweep = m.get("sweep", {})
    if not isinstance(sweep, dict):
        raise InputError(f"{where}.sweep: expected a table of lists")
    for k, v in sweep.items():
        if not isinstance(v, list) or not v:
            raise InputError(f"{where}.sweep.{k}: expected a non-empty list of values")
        if k in params:
            raise InputError(f"{where}: parameter {k!r} is set in both params and sweep; keep it in one "
                             "(the sweep would silently replace the params value)")
    pp = m.get("phantom_params", {})
    if not isinstance(pp, dict) or not all(isinstance(v, dict) for v in pp.values()):
        raise InputError(f"{where}.phantom_params: expected tables [methods.phantom_params.<phantom>]")
    kinds = m.get("noise", [])
    if not isinstance(kinds, list) or not all(k in NOISE_KINDS for k in kinds):
        raise InputError(f"{where}.noise: expected a list of noise kinds ({', '.join(NOISE_KINDS)}); got {kinds!r}")
    return MethodSpec(name=name, label=label, params=dict(params), sweep=dict(sweep),
                      phantom_params={k: dict(v) for k, v in pp.items()}, noise=tuple(kinds))


def load_config(path: str | Path) -> RunConfig:
    """Read a TOML config file (structure only; call :meth:`RunConfig.validate` before running)."""
    path = Path(path)
    data = read_toml(path, "config")
    return config_from_dict(data, source=str(path))


def builtin_config(name: str) -> RunConfig:
    """One of the shipped configurations (``paper``, ``quick``)."""
    if name not in BUILTIN_CONFIGS:
        raise InputError(f"unknown built-in config {name!r}; valid: {', '.join(BUILTIN_CONFIGS)}")
    text = (CONFIG_DIR / f"{name}.toml").read_text(encoding="utf-8")
    return config_from_dict(tomllib.loads(text), source=f"bench/configs/{name}.toml")


def parse_noise_spec(text: str) -> list[NoiseSpec]:
    """``none``, ``gaussian`` (paper SNR) or ``gaussian@40`` (40 dB); comma-separated lists allowed."""
    out = []
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        kind, at, snr = item.partition("@")
        if at:
            try:
                value: Any = float(snr)
            except ValueError:
                raise InputError(f"noise {item!r}: SNR {snr!r} is not a number (dB)") from None
        else:
            value = "paper"
        out.extend(_noise_from(kind.strip(), value, f"noise {item!r}"))
    if not out:
        raise InputError(f"noise {text!r}: no noise settings")
    return out


def parse_degrade_list(items, where: str = "--degrade") -> list[str]:
    """Degradations (``"none"``, ``"mask"``, ``"thick_slices@3+mask"``; a comma-separated text on the command
    line) as their canonical texts, each checked (:func:`phantoms.parse_degradation`), none repeated."""
    from phantoms.degrade import parse_degradation

    if isinstance(items, str):
        items = [t for t in items.split(",") if t.strip()]
    out = []
    for item in items:
        try:
            text = str(parse_degradation(item))
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
        if text in out:
            raise InputError(f"{where}: {text!r} is listed twice")
        out.append(text)
    if not out:
        raise InputError(f"{where}: no degradations")
    return out
