"""The source of the careless and hostile plug-ins the battery imports (``--import bat_*``), as text written
into the plug-in folder: methods that write to their input (cause 5), that fail in every way a method can
(cause 11), that put terminal controls in every text they provide (cause 13) or that tamper with their run
folder (cause 2); and modules that end or break the process at import (cause 6)."""

from __future__ import annotations

HEADER = '''
import ctypes, os, signal, sys
import numpy as np
import trimesh
from methods import Method, Param, Reconstruction, get_method, register_method


def mc(volume):
    return get_method("marching_cubes").reconstruct(volume).mesh


def plugin(name, body, params=None, description="a battery plug-in"):
    def reconstruct(self, volume):
        h = volume.h
        return body(self, volume, h)
    cls = type(name.title().replace("_", ""), (Method,), {
        "name": name, "description": description, "params": params or {}, "reconstruct": reconstruct})
    return register_method(cls)
'''

#: cause 5: name -> body writing to the volume before marching cubes (a 2 h shift of the level set)
WRITERS = {
    "rw_iadd": "volume.values += 2 * h",
    "rw_setitem": "volume.values[...] = volume.values + 2 * h",
    "rw_flags": "volume.values.flags.writeable = True\n    volume.values += 2 * h",
    "rw_setflags": "volume.values.setflags(write=True)\n    volume.values[...] += 2 * h",
    "rw_base": "b = volume.values\n    while b.base is not None:\n        b = b.base\n    b[...] += 2 * h",
    "rw_copyto": "np.copyto(volume.values, volume.values + 2 * h)",
    "rw_rebind": "volume.values = volume.values + 2 * h",
    "rw_origin": "volume.origin += 2 * h",
    "rw_spacing": "volume.spacing *= 1.25",
    "rw_channels": "volume.channels(0)[...] += 2 * h",
}

#: cause 11: name -> body of a method that fails
FAILING = {
    "f_bad_faces": "m = mc(volume)\n    f = m.faces.copy()\n    f[0, 0] = 10 ** 6\n"
                   "    return Reconstruction(trimesh.Trimesh(m.vertices, f, process=False), {})",
    "f_memory": "raise MemoryError()",
    "f_abort": "os.abort()",
    "f_segfault": "ctypes.string_at(0)",
    "f_kbint": "raise KeyboardInterrupt()",
    "f_none": "return None",
    "f_trimesh": "return mc(volume)",
    "f_tuple": "m = mc(volume)\n    return (m.vertices, m.faces)",
    "f_nan": "m = mc(volume)\n    v = m.vertices.copy()\n    v[3] = np.nan\n"
             "    return Reconstruction(trimesh.Trimesh(v, m.faces, process=False), {})",
    "f_huge": "m = mc(volume)\n"
              "    return Reconstruction(trimesh.Trimesh(m.vertices * 1e39, m.faces, process=False), {})",
    "f_empty": "return Reconstruction(trimesh.Trimesh(np.zeros((0, 3)), np.zeros((0, 3), int)), {})",
    "f_recursion": "def r(k):\n        return r(k + 1) + 1\n    return r(0)",
    "f_long_message": "raise RuntimeError('x' * 200000)",
    "f_sys_exit": "sys.exit(0)",
    "f_sigterm": "os.kill(os.getpid(), signal.SIGTERM)\n    import time\n    time.sleep(5)",
    "f_bad_info": "return Reconstruction(mc(volume), {'iterations': 'many', 'warnings': 'one string'})",
    "f_inside_out": "m = mc(volume)\n    return Reconstruction(trimesh.Trimesh(m.vertices, m.faces[:, ::-1], "
                    "process=False), {})",
}

EVIL = "\\x1b[2J\\x1b]0;pwned\\x07\\u202eevil\\x9b31m"

#: cause 13: name -> body, each putting terminal controls in one text the suite shows
NOISY = {
    "t_message": f"raise RuntimeError('boom {EVIL}')",
    "t_warnings": f"return Reconstruction(mc(volume), {{'warnings': ['w {EVIL}']}})",
    "t_stop_message": f"return Reconstruction(mc(volume), {{'stop_message': 'm {EVIL}', 'stop_reason': 'r {EVIL}'}})",
    "t_info_value": f"return Reconstruction(mc(volume), {{'note {EVIL}': 'v {EVIL}'}})",
    "t_prints": f"print('out {EVIL}')\n    print('err {EVIL}', file=sys.stderr)\n    os.write(1, b'fd1 \\x1b[2J')\n"
                "    return Reconstruction(mc(volume), {})",
    "t_flood": "sys.stdout.write(('\\x1b[2J' + 'y' * 1000 + '\\n') * 10000)\n    sys.stdout.flush()\n"
               "    return Reconstruction(mc(volume), {})",
    "t_html": "raise RuntimeError('<script>alert(1)</script><img src=x onerror=alert(2)>')",
}


def _defs(table: dict[str, str], description: str = "a battery plug-in") -> str:
    out = []
    for name, body in table.items():
        out.append(f"def _{name}(self, volume, h):\n    {body}\n    return Reconstruction(mc(volume), {{}})\n\n"
                   f"plugin({name!r}, _{name}, description={description!r})\n")
    return "\n".join(out)


def module_writers() -> str:
    return HEADER + _defs(WRITERS)


def module_failing() -> str:
    return HEADER + _defs(FAILING)


def module_noisy() -> str:
    """The cause-13 methods, and one whose name, description, parameter doc and choices hold controls."""
    texts = HEADER + _defs(NOISY) + f'''
plugin("t_described", lambda self, volume, h: Reconstruction(mc(volume), {{}}),
       params={{"k": Param(1, "doc {EVIL}", min=0), "mode": Param("a", "mode {EVIL}", choices=["a", "b{EVIL}"])}},
       description="describes {EVIL}")
'''
    return texts


def module_named() -> str:
    """A method whose registry name itself holds controls."""
    return HEADER + f'plugin("t_named{EVIL}", lambda self, volume, h: Reconstruction(mc(volume), {{}}))\n'


def module_tamper() -> str:
    """Cause 2: methods that delete the run folder's config.json or plant a sealed record of their own."""
    return HEADER + '''
import json
from pathlib import Path


def _deletes(self, volume, h):
    (Path(self.config["folder"]) / "config.json").unlink(missing_ok=True)
    return Reconstruction(mc(volume), {})


def _plants(self, volume, h):
    from bench.run.integrity import seal
    cells = Path(self.config["folder"]) / "cells"
    rec = seal({"row": {"cell_id": "planted", "status": "ok", "label": "planted", "hausdorff_h": 0.0},
                "cell": {}, "traceback": None, "artifacts": [], "code": None}, None)
    (cells / "planted.json").write_text(json.dumps(rec))
    return Reconstruction(mc(volume), {})


folder = {"folder": Param("", "the run folder", type=str)}
plugin("tamper_config", _deletes, params=folder)
plugin("tamper_record", _plants, params=folder)
'''


#: cause 6: module name -> its body (each ends or breaks the process at import)
AT_IMPORT = {
    "bat_exit0": "import sys\nsys.exit(0)\n",
    "bat_exit3": "import sys\nsys.exit(3)\n",
    "bat_exitmsg": "import sys\nsys.exit('bye from the plug-in')\n",
    "bat_systemexit": "raise SystemExit\n",
    "bat_kbint": "raise KeyboardInterrupt\n",
    "bat_syntax": "def broken(:\n    pass\n",
    "bat_missing": "import a_module_that_does_not_exist_anywhere\n",
    "bat_newline": "raise RuntimeError('first line\\nsecond line\\nthird')\n",
    "bat_controls": f"raise ImportError('bad {EVIL}')\n",
    "bat_os_exit": "import os\nos._exit(0)\n",
}
