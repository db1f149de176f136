"""The ``meshbits`` program: its parser, assembled from one ``add_*`` function per
command, and :func:`main`, which runs a command and turns every outcome into an exit code
(see :mod:`meshbits.cli`)."""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

from .. import __version__
from ..errors import MeshbitsError, UnreachableBudgetError, one_line
from .batch import add_batch
from .calibrate import add_calibrate
from .common import (
    EXIT_BAD_INPUT,
    EXIT_BROKEN_PIPE,
    EXIT_INTERNAL,
    EXIT_INTERRUPTED,
    EXIT_TERMINATED,
    EXIT_UNMET,
    UserError,
    print_json,
)
from .compress import add_compress, add_demo
from .hausdorff import add_hausdorff
from .info import add_info, add_k
from .plan import add_plan
from .plot import add_plot
from .quantize import add_quantize

__all__ = ["build_parser", "main"]

#: The subcommands, in the order ``meshbits --help`` lists them.
_COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    add_k,
    add_info,
    add_demo,
    add_plan,
    add_compress,
    add_batch,
    add_calibrate,
    add_hausdorff,
    add_quantize,
    add_plot,
)


class _UsageError(Exception):
    """A command line that does not parse: its one-line message."""


class _Parser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line on stderr, exit code 2 (and,
    with ``--json``, a JSON object on stdout: see :func:`main`)."""

    def error(self, message: str) -> NoReturn:
        raise _UsageError(f"{self.prog}: error: {message} (see {self.prog} --help)")


def build_parser() -> argparse.ArgumentParser:
    """The ``meshbits`` parser: ``--version``, ``--debug`` and one subparser per command."""
    parser = _Parser(
        prog="meshbits",
        description="How many vertices, and how many bits per coordinate, should a mesh keep?",
        epilog="Exit codes: 0 done (budget met), 1 budget not met, 2 bad input, "
        "3 internal error, 130 interrupted.",
    )
    parser.add_argument("--version", action="version", version=f"meshbits {__version__}")
    debug_help = "on an internal error, print the whole traceback"
    parser.add_argument("--debug", action="store_true", help=debug_help)
    sub = parser.add_subparsers(dest="command", required=True)
    for add in _COMMANDS:
        add(sub)
    for command in sub.choices.values():
        # Also after the subcommand; SUPPRESS keeps the main parser's value when absent.
        command.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help=debug_help
        )
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``meshbits`` program; returns the exit code (see the module
    docstring)."""
    parser = build_parser()
    words = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(words)
    except SystemExit as done:  # --help or --version, already printed
        return done.code if isinstance(done.code, int) else EXIT_BAD_INPUT
    except _UsageError as err:
        print(err, file=sys.stderr)
        if "--json" in words:
            print_json({"error": str(err), "exit_code": EXIT_BAD_INPUT})
        return EXIT_BAD_INPUT
    where = f"meshbits {args.command}"
    previous = _catch_termination()
    try:
        return int(args.run(args))
    except BrokenPipeError:
        # The reader of stdout went away (``| head``): no traceback, nothing more to say.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_BROKEN_PIPE
    except KeyboardInterrupt as err:
        # Ctrl-C, or SIGTERM (raised as _Terminated): temporary files were removed on the
        # way out.
        if isinstance(err, _Terminated):
            print(f"{where}: terminated", file=sys.stderr)
            return _failed(args, "terminated", EXIT_TERMINATED)
        print(f"{where}: interrupted", file=sys.stderr)
        return _failed(args, "interrupted", EXIT_INTERRUPTED)
    except (UserError, MeshbitsError, OSError) as err:
        # Refused input, an unusable file, or a file system that refused a read or write.
        message = one_line(err)
        mesh = getattr(args, "mesh", None)
        if isinstance(err, MeshbitsError) and isinstance(mesh, Path) and mesh.name not in message:
            # Found in the mesh once read (no surface, a budget it cannot meet...): name it.
            message = f"{mesh.name}: {message}"
        if isinstance(err, UnreachableBudgetError):
            message += "; nothing written"
            print(f"{where}: budget not met: {message}", file=sys.stderr)
            return _failed(args, message, EXIT_UNMET)
        print(f"{where}: error: {message}", file=sys.stderr)
        return _failed(args, message, EXIT_BAD_INPUT)
    except Exception as err:
        if args.debug:
            traceback.print_exc()
        print(
            f"{where}: internal error (a bug in meshbits {__version__}, please report it): "
            f"{type(err).__name__}: {one_line(err)}"
            + ("" if args.debug else "; rerun with --debug for the traceback"),
            file=sys.stderr,
        )
        return _failed(
            args, f"internal error: {type(err).__name__}: {one_line(err)}", EXIT_INTERNAL
        )
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program is, as Ctrl-C is, so that what it was writing is
    cleaned up (its temporary files and folders) before it exits."""


def _raise_terminated(signum: int, frame: object) -> NoReturn:
    raise _Terminated


def _catch_termination() -> Any:
    """Turn SIGTERM into :class:`_Terminated` while a command runs (from the main thread
    only, where Python runs signal handlers); returns the handler to put back, if any."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _raise_terminated)


def _failed(args: argparse.Namespace, message: str, code: int) -> int:
    """With ``--json``, a failure is a JSON object on stdout too (``error``, ``exit_code``),
    so that a pipeline reading stdout gets a document either way; returns ``code``."""
    if getattr(args, "json", False):
        print_json({"error": message, "exit_code": code})
    return code
