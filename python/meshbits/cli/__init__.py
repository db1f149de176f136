"""The ``meshbits`` command line.

Every subcommand prints a short human-readable report, or one JSON object with
``--json`` (strict JSON: a value that is not a finite number is ``null``). Exit codes:

- 0: done (``compress``: the budget was met);
- 1: a budget could not be met (the closest result is still reported, and written,
  but for a budget no output can meet, such as a size below a scene's images, and a
  float32 output that cannot hold the mesh where it lies: then nothing is written);
- 2: bad arguments, or an input file that cannot be used (one line on stderr);
- 3: an internal error, a bug in meshbits (one line on stderr; ``--debug`` shows the
  traceback);
- 130: interrupted (Ctrl-C); 143: terminated (SIGTERM); either way the files being
  written are removed;
- 141: the reader of stdout closed it (``meshbits ... | head``), silently.

With ``--json`` a failure (2, 3, 130; usage errors too) is also one JSON object on stdout,
``{"error": message, "exit_code": code}``.

A JSON report of a file names the unit of its lengths in ``length_unit``: ``"m"`` for
glTF (whose unit is the meter), else ``"mesh units"`` (the file's own coordinates, which
carry no unit); areas are in that unit squared.

Arguments and output folders are checked before any file is read.

One module per command or command family: :mod:`.info` (``k``, ``info``), :mod:`.compress`
(``compress``, ``demo``), :mod:`.plan`, :mod:`.batch`, :mod:`.calibrate`,
:mod:`.hausdorff`, :mod:`.quantize`, :mod:`.plot`; :mod:`.common` holds what they share
(exit codes, printing, argument types, the one budget argument group) and :mod:`.main`
assembles the parser. ``python -m meshbits.cli`` runs :func:`main`.
"""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
