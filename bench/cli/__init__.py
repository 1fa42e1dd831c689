"""The command line: ``python -m bench <command> ...`` — argument parsing and exit codes only.

Each room registers its subcommands (``register(subparsers)``): :mod:`.volumes` (phantoms, volume, info),
:mod:`.run` (run, report), :mod:`.methods` (methods, reconstruct), :mod:`.check` (check-method), :mod:`.perf` (perf).  Errors a user can fix
(:class:`phantoms.InputError`) print one line on stderr and exit with code 2, never a traceback.
"""

from __future__ import annotations

import argparse
import sys

from methods import ReconstructionFailed
from phantoms import InputError

from . import check as _check
from . import methods as _methods
from . import perf as _perf
from . import run as _run
from . import volumes as _volumes

EXIT_USAGE = 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m bench",
                                     description="levelset-bench: benchmark surface reconstruction from "
                                                 "level-set volumes.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for room in (_volumes, _run, _methods, _check, _perf):
        room.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except ReconstructionFailed as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
