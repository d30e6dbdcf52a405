"""Argument checks shared by sub-commands (not a sub-command itself)."""

from __future__ import annotations

from pathlib import Path

from vega_core.errors import BadArgument

__all__ = ["npz_out"]


def npz_out(text: str) -> Path:
    """The ``--out`` file of a command that writes an ``.npz`` (+ its ``.json``): must end in
    ``.npz`` and not be a directory (BadArgument: one line, exit 2)."""
    out = Path(text)
    if out.suffix != ".npz":
        raise BadArgument(f"--out {out}: must end in .npz")
    if out.is_dir():
        raise BadArgument(f"--out {out}: is a directory")
    return out
