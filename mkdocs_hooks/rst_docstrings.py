"""A griffe extension for the docs site: the project's docstrings, written numpydoc-ish with reST
roles, rendered by mkdocstrings' numpy parser without raw markup.

Rewrites each docstring before it is parsed (nothing in ``src`` changes):

* ``:mod:`~a.b``` (also ``:func:``, ``:class:``, ``:meth:``, ``:data:``, ``:attr:``, ``:exc:``,
  ``:obj:``, ``:const:``) → an optional cross-reference: a link where mkdocstrings knows the
  object, plain code otherwise (``~`` shows the last name only);
* ``:math:`x``` → ``$x$`` and a ``.. math::`` block → a ``$$ … $$`` block (``pymdownx.arithmatex``,
  rendered by MathJax in the browser);
* ``:cite:`key``` → ``[key]``;
* a reST simple table (``=====  =====`` borders above, below the header and at the end; a row
  whose first cell is blank continues the row above) → a Markdown table;
* an item ``name : text`` of a Parameters/Attributes/Returns/Raises… section whose ``text`` is
  prose (the project's short form) → ``name`` with ``text`` as its description, so that the
  "Type" column holds only types; a wrapped line at the item's indentation joins the item
  above; a Returns/Raises section that is prose from its first line becomes a titled box
  ("Raises, in words").
"""

from __future__ import annotations

import re
from typing import Any

import griffe

ROLE = re.compile(r":(?:py:)?(mod|func|class|meth|data|attr|exc|obj|const):`(~?)([^`<]+?)"
                  r"(?:\s*<([^>`]+)>)?`")
MATH_ROLE = re.compile(r":math:`([^`]+)`")
CITE = re.compile(r":cite(?:[pt])?:`([^`]+)`")
DIRECTIVE = re.compile(r"^(\s*)\.\. math::[ \t]*(.*)$")
BORDER = re.compile(r"^(\s*)=+(?: +=+)+\s*$")
ITEM = re.compile(r"^(\s*)([\w\*][\w\*, ]*?) : (.+)$")
SECTIONS = ("Parameters", "Other Parameters", "Attributes", "Keyword Arguments", "Returns",
            "Yields", "Raises", "Warns")
#: Words that make ``name : text`` prose, not a type.
PROSE = re.compile(r"\b(the|a|an|to|for|is|are|in|on|with|from|at|per|each|this|that|not|as|"
                   r"by|if|when|its|their|be|all|one|which|what|how)\b|\.$|;", re.IGNORECASE)


def _role(match: re.Match) -> str:
    tilde, text, target = match.group(2), match.group(3).strip(), match.group(4)
    identifier = (target or text).strip().rstrip("()")
    shown = text if target else (text.split(".")[-1] if tilde else text)
    return f'<autoref identifier="{identifier}" optional><code>{shown}</code></autoref>'


def convert_math(text: str) -> str:
    """``.. math::`` blocks (directive line plus its more-indented lines) → ``$$`` blocks."""
    lines, out, k = text.split("\n"), [], 0
    while k < len(lines):
        found = DIRECTIVE.match(lines[k])
        if not found:
            out.append(lines[k])
            k += 1
            continue
        indent, body = found.group(1), [found.group(2)] if found.group(2).strip() else []
        k += 1
        while k < len(lines) and (not lines[k].strip()
                                  or len(lines[k]) - len(lines[k].lstrip()) > len(indent)):
            body.append(lines[k])
            k += 1
        while body and not body[-1].strip():
            body.pop()
        out += ["", f"{indent}$$", *[f"{indent}{b.strip()}" for b in body if b.strip()],
                f"{indent}$$", ""]
    return "\n".join(out)


def _cells(line: str, spans: list[tuple[int, int]]) -> list[str]:
    """The cells of a table row cut at the border's column ``spans`` (the last one open)."""
    return [line[a:b if k + 1 < len(spans) else None].strip()
            for k, (a, b) in enumerate(spans)]


def _table(lines: list[str], spans: list[tuple[int, int]]) -> list[list[str]]:
    """Rows of a simple table's body; a line whose first cell is blank continues the row
    above."""
    rows: list[list[str]] = []
    for line in lines:
        if not line.strip():
            continue
        cells = _cells(line, spans)
        if rows and not cells[0]:
            rows[-1] = [f"{a} {b}".strip() for a, b in zip(rows[-1], cells)]
        else:
            rows.append(cells)
    return rows


def _row(indent: str, cells: list[str]) -> str:
    """One Markdown table row (a ``|`` inside a cell escaped)."""
    return indent + "| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |"


def convert_tables(text: str) -> str:
    """reST simple tables (three borders: top, under the header, bottom) → Markdown tables;
    anything else is left as it is."""
    lines, out, k = text.split("\n"), [], 0
    while k < len(lines):
        top = BORDER.match(lines[k])
        borders = [j for j in range(k + 1, len(lines)) if BORDER.match(lines[j])][:2] \
            if top else []
        if len(borders) < 2 or lines[borders[0]] != lines[k] or lines[borders[1]] != lines[k]:
            out.append(lines[k])
            k += 1
            continue
        indent = top.group(1)
        spans = [(m.start(), m.end()) for m in re.finditer(r"=+", lines[k])]
        spans = [(a, spans[n + 1][0] if n + 1 < len(spans) else b)
                 for n, (a, b) in enumerate(spans)]
        header = _table(lines[k + 1:borders[0]], spans)
        body = _table(lines[borders[0] + 1:borders[1]], spans)
        out += ["", *(_row(indent, h) for h in header[:1]),
                indent + "|" + "|".join(" --- " for _ in spans) + "|",
                *(_row(indent, r) for r in body), ""]
        k = borders[1] + 1
    return "\n".join(out)


def is_prose(text: str) -> bool:
    """``text`` reads as a description, not a type: a common English word, a full stop or a
    semicolon, a backquote (a literal or a role: markup the "Type" column would show raw), or
    more than five words (``|`` not counted)."""
    words = [w for w in text.split() if w != "|"]
    return bool(PROSE.search(text)) or "`" in text or len(words) > 5


def _section_lines(lines: list[str], start: int, base: int) -> int:
    """Index after the section whose first body line is ``start`` (next header or end)."""
    k = start
    while k < len(lines):
        if (k + 1 < len(lines) and set(lines[k + 1].strip()) == {"-"} and lines[k].strip()
                and len(lines[k]) - len(lines[k].lstrip()) == base):
            return k
        k += 1
    return k


def _rewrite_section(title: str, body: list[str], base: int) -> list[str] | None:
    """The section's body with prose moved out of the type slots; ``None``: the section is
    prose from its first line (render it as a paragraph instead)."""
    pad, out, seen_item = " " * base, [], False
    for line in body:
        indent = len(line) - len(line.lstrip())
        if not line.strip() or indent > base:
            out.append(line)
            continue
        found = ITEM.match(line)
        if found:
            name, text = found.group(2), found.group(3)
            if title in ("Raises", "Warns") or is_prose(text):
                out += [f"{pad}{name}" + (" :" if title in ("Returns", "Yields") else ""),
                        f"{pad}    {text}"]
            else:
                out.append(line)
            seen_item = True
        elif is_prose(line.strip()):
            if not seen_item:
                return None
            out.append(f"{pad}    {line.strip()}")   # a wrapped line of the item above
        else:
            out.append(line)
            seen_item = True
    return out


def convert_items(text: str) -> str:
    """The item sections (:data:`SECTIONS`) in numpydoc form: ``name`` (and a type) on the item
    line, the description indented under it (module docstring)."""
    lines, out, k = text.split("\n"), [], 0
    while k < len(lines):
        line = lines[k]
        header = (line.strip() in SECTIONS and k + 1 < len(lines)
                  and set(lines[k + 1].strip()) == {"-"})
        if not header:
            out.append(line)
            k += 1
            continue
        base = len(line) - len(line.lstrip())
        end = _section_lines(lines, k + 2, base)
        body = _rewrite_section(line.strip(), lines[k + 2:end], base)
        if body is None:       # prose: a titled box ("Raises, in words") holding the text
            title = f"{line.strip()}, in words"
            out += [f"{' ' * base}{title}", f"{' ' * base}{'-' * len(title)}",
                    *lines[k + 2:end]]
        else:
            out += [line, lines[k + 1], *body]
        k = end
    return "\n".join(out)


def convert(text: str) -> str:
    """The whole rewrite (module docstring)."""
    text = convert_items(convert_math(convert_tables(text)))
    text = MATH_ROLE.sub(lambda m: f"${m.group(1)}$", text)
    text = CITE.sub(lambda m: f"[{m.group(1)}]", text)
    return ROLE.sub(_role, text)


class RstDocstrings(griffe.Extension):
    """Rewrites every docstring with :func:`convert` as griffe loads it."""

    def on_instance(self, *, obj: Any, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = convert(obj.docstring.value)
