"""Text for the terminal: whatever came from a file is printed without its control characters.

A slab id, a capture folder's name or a key in a design file is text a user (or anyone who
sent them the file) chose. Printed as it is, a newline in it starts a line that looks like the
command's own (``slab S-1: ACCEPTED``), an escape sequence moves the cursor or recolours the
screen, and a right-to-left override turns a verdict around. :func:`clean` shows every such
character as an escape (``\\n``, ``\\x1b``, ``\\u202e``) instead.
"""

from __future__ import annotations

import unicodedata

__all__ = ["clean"]

_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escape(ch: str) -> str:
    if ch in _NAMED:
        return _NAMED[ch]
    code = ord(ch)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def clean(text) -> str:
    """``text`` with every control or invisible formatting character (Unicode categories Cc, Cf,
    Zl, Zp: newlines, escapes, bidirectional overrides, zero-width characters) written as a
    visible escape, so that one printed line stays one line and reads as it is.

    Examples
    --------
    >>> clean("S-1\\nslab S-1: ACCEPTED")
    'S-1\\\\nslab S-1: ACCEPTED'
    >>> clean("\\x1b[2J"), clean("ok")
    ('\\\\x1b[2J', 'ok')
    """
    text = str(text)
    if text.isprintable():
        return text
    return "".join(_escape(ch) if unicodedata.category(ch) in ("Cc", "Cf", "Zl", "Zp") else ch for ch in text)
