"""The error core: what counts as bad input, and how an error becomes one line.

Every VEGA package rejects input a user can correct — a file, a command-line argument, a node
parameter, an environment variable — by raising :class:`BadInput` (or a subclass) with a
one-line message that names the input and the problem. The two front ends, the ``vega``
command line (:func:`vega_cli.cli.main`) and every node (:func:`vega_bus.shell.run_node`), map
errors the same way:

* :class:`BadInput` and ``OSError`` (a file that cannot be read or written): one line on
  stderr (``vega: error: <message>`` / ``<node>: <message>``), exit status 2;
* anything else (a ``ValueError`` from numpy, a ``KeyError``, a ``ZeroDivisionError``, …) is a
  defect: the traceback on stderr, exit status 1.

The classes subclass ``ValueError``, so every ``except ValueError`` and
``pytest.raises(ValueError)`` keeps catching them; a plain ``ValueError`` is reserved for
internal checks (invariants, numerical failures, programming errors).
The shape follows python-control's ``control/exception.py``: a few classes on the standard
exceptions, named for what went wrong, not for where.
"""

from __future__ import annotations

__all__ = ["BadInput", "BadFile", "BadArgument", "one_line"]


class BadInput(ValueError):
    """Input a user can correct was rejected; the message is one line naming it."""


class BadFile(BadInput):
    """A file (document, controller table, bag) is missing, unreadable or malformed."""


class BadArgument(BadInput):
    """A command-line argument, node parameter or environment variable is out of its domain."""


def one_line(exc: BaseException) -> str:
    """The message of ``exc`` on one line: whitespace runs (newlines included) collapsed to
    one space; the exception's type name if the message is empty."""
    return " ".join(str(exc).split()) or type(exc).__name__
