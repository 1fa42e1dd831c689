"""The command line: ``python -m bench <command> ...`` — argument parsing and exit codes only.

Each room registers its subcommands (``register(subparsers)``): :mod:`.volumes` (phantoms, volume, info),
:mod:`.run` (run, report), :mod:`.methods` (methods, reconstruct), :mod:`.check` (check-method), :mod:`.perf` (perf),
:mod:`.compare` (compare), :mod:`.table` (table).  Errors a user can fix
(:class:`phantoms.InputError`) print one line on stderr and exit with code 2, never a traceback; so do argparse's
own (a bad option value, an unknown choice, two exclusive options): :class:`OneLineParser` prints the error and
where the usage is, not argparse's usage block.
"""

from __future__ import annotations

import argparse
import sys

from methods import ReconstructionFailed
from phantoms import InputError

from ..terminal import printable

from . import check as _check
from . import compare as _compare
from . import methods as _methods
from . import perf as _perf
from . import run as _run
from . import table as _table
from . import volumes as _volumes

EXIT_USAGE = 2


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr and exit 2, as every other error of the command
    line (argparse prints a 5–11-line usage block first).  Subcommand parsers inherit the class
    (``add_subparsers`` makes its parsers of the parent's type); ``--help`` is unchanged."""

    def error(self, message: str):
        line = printable(message).replace("\n", "\\n").replace("\t", "\\t")  # argv text can hold newlines
        self.exit(EXIT_USAGE, f"error: {line} (usage: {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="python -m bench",
                           description="levelset-bench: benchmark surface reconstruction from level-set volumes.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for room in (_volumes, _run, _methods, _check, _perf, _compare, _table):
        room.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe (``info f | head``) shows up here, not at interpreter exit
        return code
    except BrokenPipeError:
        return quiet_broken_pipe()
    except InputError as exc:
        print(f"error: {_capped(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except ReconstructionFailed as exc:
        print(f"error: {_capped(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except OSError as exc:  # a write error a command did not name itself: still one line with path and cause
        if exc.filename is None:
            raise
        print(printable(f"error: {exc.filename}: {exc.strerror or exc}"), file=sys.stderr)
        return EXIT_USAGE


#: characters of an error message shown (a plug-in's message can be megabytes)
MAX_ERROR = 2000


def _capped(exc: BaseException) -> str:
    """The error's text on one line, escaped, cut to :data:`MAX_ERROR` characters with its full length said."""
    text = printable(exc).replace("\n", " ")
    return text if len(text) <= MAX_ERROR else f"{text[:MAX_ERROR]}… ({len(text):,} characters)"


def quiet_broken_pipe() -> int:
    """The reader of stdout went away (``| head``): stop quietly, as Unix tools do, without a traceback at
    exit (stdout is pointed at /dev/null so the final flush cannot fail again)."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 141  # 128 + SIGPIPE, the shell's code for a process stopped by a closed pipe


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
