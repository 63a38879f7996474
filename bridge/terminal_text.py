"""Text from files and vehicles, made safe to print on a terminal.

Owns printable(): every control character becomes a visible escape (ESC as \\x1b, BEL as \\x07, CR as \\r, a
newline as \\n, a right-to-left override as \\u202e), so a map's name, a building's id, an error that quotes a
file or a vehicle's STATUSTEXT can neither move the cursor, recolour the terminal, ring it, rewrite a line
already printed (CR) nor split one message into two. No exception: a file's text never gets to move the cursor,
not even with a tab or a newline. The command line applies it where it prints (the error line of
`missionplan`, plan's and status's summaries, fly's alerts and problems, the mock's log); the files written
(report.json, GeoJSON, HTML) keep the text as it was: they have their own escaping.
"""

from __future__ import annotations

import unicodedata

# Unicode's other line and paragraph separators and the bidirectional controls (which reorder what a
# terminal shows: "Trojan source") are escaped with the C0 / C1 controls.
_ALSO_ESCAPED = frozenset("\u2028\u2029\u200e\u200f\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escape(char: str) -> str:
    if char in _NAMED:
        return _NAMED[char]
    code = ord(char)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def printable(text: object) -> str:
    """str(text) with every control character (C0, DEL, C1, Unicode line separators and bidirectional
    controls) written as a visible backslash escape; all other characters, accents and scripts included, as
    they are."""
    text = str(text)
    if text.isprintable():  # the common case (false for every Cc, Cf, Zl and Zp character): nothing to escape
        return text
    return "".join(_escape(char) if (unicodedata.category(char) in ("Cc", "Zl", "Zp") or char in _ALSO_ESCAPED)
                   else char for char in text)
