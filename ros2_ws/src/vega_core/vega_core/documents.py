"""Reading the project's text data files with a one-line error (the loaders' shared first step)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["read_text"]


def read_text(path: str | Path, what: str, error: type[Exception] = ValueError) -> str:
    """Contents of the UTF-8 file ``path``.

    Raises
    ------
    error
        ``"<path>: cannot read <what> (<reason>)"`` if the file is missing, unreadable or not
        UTF-8 — one line, no traceback chain.
    """
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or type(exc).__name__
        raise error(f"{path}: cannot read {what} ({reason})") from None
