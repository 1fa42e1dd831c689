"""Surface-reconstruction methods behind one interface (:mod:`methods.base`).

This package exports what a method author uses: the class to subclass and its parameter spec, what
``reconstruct`` returns or raises, the input check, the registry calls a plug-in makes, the ``info`` keys the suite
reads and the cost model's form.  The suite's own calls of a method (the guarded ``reconstruct``, the hooks, the
return checks) are in :mod:`methods.contract`; the registry's internals in :mod:`methods.registry`.
"""

from .base import Method, check_volume
from .contract import INFO_KEYS, MethodSkipped, Reconstruction, ReconstructionFailed
from .cost_model import PowerLaw, crossing_cells
from .params import Param
from .registry import available_methods, get_method, import_plugins, register_method

__all__ = [
    "Method", "Param", "Reconstruction", "ReconstructionFailed", "MethodSkipped", "check_volume", "INFO_KEYS",
    "register_method", "get_method", "available_methods", "import_plugins", "PowerLaw", "crossing_cells",
]
