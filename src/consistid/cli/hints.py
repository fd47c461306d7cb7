"""Error hints in the syntax of the place the user writes: TOML for the ``consistid`` command.

The library's messages name options as Python keyword arguments (``mode='nearest'``,
``friction=('coulomb', 'viscous')``, ``armature=True``); a CLI user writes them in a TOML
configuration, as ``mode = "nearest"``, ``friction = ["coulomb", "viscous"]``,
``armature = true``. :func:`toml_hints` rewrites every ``name=<Python literal>`` of a message
into ``name = <TOML value>`` and the quoted choices of an ``allowed:`` list into TOML strings.
``None`` has no TOML spelling (a key is left out instead): ``name=None`` stays as it is, and in an
``allowed:`` list it reads "(the key left out)". What is not a Python literal (``x=f(y)``) stays.
"""

from __future__ import annotations

import ast
import json
import math
import re
from typing import Any

_ASSIGN = re.compile(r"(?<![\w.=!<>])([A-Za-z_][A-Za-z0-9_]*)=(?!=)")
_SIMPLE = re.compile(r"""'(?:[^'\\]|\\.)*'|"(?:[^"\\]|\\.)*"|[-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?"""
                     r"""|\.\d+(?:[eE][-+]?\d+)?|inf)|True|False|None""")
_CLOSE = {"(": ")", "[": "]", "{": "}"}


def _literal_at(text: str, start: int) -> tuple[Any, int] | None:
    """The Python literal that starts at ``text[start]`` and where it ends, or ``None``."""
    if start >= len(text):
        return None
    if text[start] in _CLOSE:
        depth, quote = 0, ""
        for k in range(start, len(text)):
            c = text[k]
            if quote:
                if c == quote and text[k - 1] != "\\":
                    quote = ""
            elif c in "'\"":
                quote = c
            elif c in _CLOSE:
                depth += 1
            elif c in _CLOSE.values():
                depth -= 1
                if depth == 0:
                    try:
                        return ast.literal_eval(text[start:k + 1]), k + 1
                    except (ValueError, SyntaxError):
                        return None
        return None
    m = _SIMPLE.match(text, start)
    if m is None:
        return None
    end = m.end()
    if end < len(text) and (text[end].isalnum() or text[end] == "_"):
        return None                                    # part of a longer word: x=Nonesuch
    token = m.group(0)
    return (float(token) if token.lstrip("+-") == "inf" else ast.literal_eval(token)), end


def toml_value(value: Any) -> str | None:
    """``value`` in TOML syntax, or ``None`` when TOML cannot spell it."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return "nan" if math.isnan(value) else repr(value)
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, (list, tuple)):
        items = [toml_value(v) for v in value]
        return None if any(i is None for i in items) else "[" + ", ".join(items) + "]"
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        items = [(k, toml_value(v)) for k, v in value.items()]
        if any(v is None for _, v in items):
            return None
        return "{" + ", ".join(f"{_toml_key(k)} = {v}" for k, v in items) + "}"
    return None


def _toml_key(key: str) -> str:
    """``key`` bare when TOML allows it (letters, digits, ``_``, ``-``), else quoted: a key
    holding ``=``, a space or a newline must not change the table it is written into."""
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else json.dumps(key, ensure_ascii=False)


def toml_hints(message: str) -> str:
    """``message`` with its Python-syntax option hints written as TOML (module docstring)."""
    out, i = [], 0
    for m in _ASSIGN.finditer(message):
        if m.start() < i:
            continue
        found = _literal_at(message, m.end())
        if found is None:
            continue
        value, end = found
        spelled = toml_value(value)
        if spelled is None:
            continue
        out += [message[i:m.start()], f"{m.group(1)} = {spelled}"]
        i = end
    out.append(message[i:])
    text = "".join(out)
    return re.sub(r"(allowed: )((?:(?:'[^']*'|None)(?:, )?)+)", _allowed, text)


def _allowed(m: re.Match) -> str:
    """An ``allowed:`` list with TOML strings; ``None`` (no TOML spelling) as leaving the key
    out."""
    items = re.sub(r"'([^']*)'", r'"\1"', m.group(2))
    return m.group(1) + re.sub(r"\bNone\b", "(the key left out)", items)


#: Python calls quoted by the library's text, and the ``consistid`` option that does the same.
CLI_SPELLINGS = {"summary(max_rows=None)": "--all",
                 "res.envelope": "result.json's \"envelope\""}


def cli_text(text: str) -> str:
    """``text`` (a result's summary) with the Python calls it quotes written as the CLI's
    options (:data:`CLI_SPELLINGS`): "… 12 more rows (--all shows all)"."""
    for python, cli in CLI_SPELLINGS.items():
        text = text.replace(python, cli)
    return text
