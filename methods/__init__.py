"""Surface-reconstruction methods behind one interface (see :mod:`methods.base`)."""

from .base import (
    BUILTIN_METHODS,
    ENTRY_POINT_GROUP,
    Method,
    Param,
    Reconstruction,
    available_methods,
    check_volume,
    get_method,
    import_plugins,
    method_names,
    register_method,
)

__all__ = [
    "Method", "Param", "Reconstruction", "available_methods", "get_method", "method_names",
    "register_method", "check_volume", "ENTRY_POINT_GROUP", "BUILTIN_METHODS",
    "import_plugins",
]
