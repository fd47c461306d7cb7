"""Text the library writes into files that other programs open: names checked, cells defused.

Two rules for every name (a joint, link or parameter name from a URDF or a log) that reaches a
written file:

* **Refused when it cannot be written as it is** (:func:`check_writable_name`): a control
  character (a newline in a joint name would start a new line of a CSV or TOML file, above its
  header) or more than :data:`MAX_NAME` characters.
* **Defused in spreadsheet cells** (:func:`spreadsheet_cell`): a cell that begins with ``=``,
  ``+``, ``-``, ``@``, a tab or a carriage return is read as a formula by Excel, LibreOffice
  and Google Sheets (OWASP, "CSV Injection"); it is written with a leading ``'``, which those
  programs show as text. Numbers are written by the writers themselves and never pass here.
"""

from __future__ import annotations

from typing import Callable

from .errors import ModelError

__all__ = ["MAX_NAME", "FORMULA_STARTS", "check_writable_name", "spreadsheet_cell"]

MAX_NAME = 1000
#: First characters that make a spreadsheet read a cell as a formula.
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")


def _control(c: str) -> bool:
    return ord(c) < 32 or 127 <= ord(c) < 160 or c in "\u2028\u2029"


def check_writable_name(name: object, where: str,
                        error: Callable[[str], Exception] = ModelError) -> str:
    """``name`` if it is printable text of 1 to :data:`MAX_NAME` characters, else ``error``
    (default :class:`~consistid.errors.ModelError`) saying where and what to do."""
    if not isinstance(name, str) or not name:
        raise error(f"{where} {name!r} is not a name (a non-empty string)")
    bad = [c for c in name if _control(c)]
    if bad or len(name) > MAX_NAME:
        what = f"control character {bad[0]!r}" if bad else f"{len(name)} characters"
        raise error(f"{where} {name[:80]!r} holds a {what}: a name must be printable text of "
                    f"at most {MAX_NAME} characters, or the files written from it (CSV, TOML, "
                    "URDF, MJCF) would break; rename it")
    return name


def spreadsheet_cell(text: str) -> str:
    """``text`` as a CSV cell no spreadsheet evaluates: a leading ``'`` before a formula start
    (:data:`FORMULA_STARTS`), and control characters written as ``\\n``-style escapes."""
    text = "".join(c.encode("unicode_escape").decode("ascii") if _control(c) and c != "\t"
                   else c for c in text)
    return "'" + text if text.startswith(FORMULA_STARTS) else text
