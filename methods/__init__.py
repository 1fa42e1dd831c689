"""Surface-reconstruction methods behind one interface (see :mod:`methods.base`)."""

from .base import (
    BUILTIN_METHODS,
    ENTRY_POINT_GROUP,
    INFO_KEYS,
    Method,
    MethodSkipped,
    Param,
    Reconstruction,
    ReconstructionFailed,
    WrongReturnType,
    as_reconstruction,
    available_methods,
    check_info,
    check_skip,
    check_volume,
    get_method,
    import_plugins,
    method_names,
    register_method,
    run_reconstruct,
    run_warm_up,
)
from .cost_model import PowerLaw, crossing_cells

__all__ = [
    "Method", "Param", "Reconstruction", "ReconstructionFailed", "available_methods", "get_method", "method_names",
    "register_method", "import_plugins", "as_reconstruction", "WrongReturnType", "check_volume", "check_info",
    "run_reconstruct", "MethodSkipped", "check_skip", "run_warm_up",
    "ENTRY_POINT_GROUP", "BUILTIN_METHODS", "INFO_KEYS", "PowerLaw", "crossing_cells",
]
