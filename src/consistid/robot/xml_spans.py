"""Where each element of an XML file sits, and edits of its start tag that leave every other
byte as it was.

A real parser (expat, the one under :mod:`xml.etree`) reports each element's start offset;
the start tag's end is found by scanning for the ``>`` outside quoted attribute values. Edits
are byte ranges replaced in the original text, so comments, attribute order, quoting, spacing
and everything outside the edited spans are kept byte for byte (a re-serialisation would not).
Only call this on text that :mod:`defusedxml` accepted (no DTD, no entities).
"""

from __future__ import annotations

import re
import xml.parsers.expat
from dataclasses import dataclass, field


@dataclass
class Element:
    """One element: its tag, attributes, parent (index into the element list, -1 for the
    root), and the byte span ``[start, tag_end)`` of its start tag (``self_closing``: ``/>``)."""

    tag: str
    attrs: dict[str, str]
    parent: int
    start: int
    tag_end: int = 0
    self_closing: bool = False
    children: list[int] = field(default_factory=list)


def _tag_end(data: bytes, start: int) -> int:
    """Offset just past the ``>`` closing the start tag at ``start`` (quotes skipped)."""
    quote = None
    for k in range(start + 1, len(data)):
        c = data[k:k + 1]
        if quote is not None:
            if c == quote:
                quote = None
        elif c in (b'"', b"'"):
            quote = c
        elif c == b">":
            return k + 1
    raise ValueError(f"unterminated start tag at byte {start}")


def elements(data: bytes) -> list[Element]:
    """Every element of the UTF-8 XML ``data`` in document order."""
    parser = xml.parsers.expat.ParserCreate("utf-8")
    found: list[Element] = []
    stack: list[int] = []

    def start(tag: str, attrs: dict[str, str]) -> None:
        at = parser.CurrentByteIndex
        end = _tag_end(data, at)
        el = Element(tag, dict(attrs), stack[-1] if stack else -1, at, end,
                     data[end - 2:end] == b"/>")
        if stack:
            found[stack[-1]].children.append(len(found))
        stack.append(len(found))
        found.append(el)

    def end(tag: str) -> None:
        stack.pop()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.Parse(data, True)
    return found


_NAME = re.compile(rb"<[^\s/>]+")
_ATTR = re.compile(rb"""(\s+)([^\s=/>]+)\s*=\s*(["'])(.*?)\3""", re.S)


def _find_attribute(data: bytes, el: Element, name: str) -> re.Match[bytes] | None:
    """The match of attribute ``name`` in ``el``'s start tag (groups: leading whitespace, name,
    quote, value), scanning the attributes in order (a value is never searched)."""
    at = _NAME.match(data, el.start).end()
    while True:
        found = _ATTR.match(data, at, el.tag_end)
        if found is None:
            return None
        if found.group(2) == name.encode():
            return found
        at = found.end()


def set_attribute(data: bytes, el: Element, name: str, value: str
                  ) -> tuple[int, int, bytes]:
    """The edit ``(start, end, replacement)`` that sets attribute ``name`` of ``el``'s start tag
    to ``value``: the old value's bytes replaced (quote kept), or `` name="value"`` added before
    the tag's ``>``/``/>``."""
    found = _find_attribute(data, el, name)
    if found is not None:
        return found.start(4), found.end(4), value.encode()
    at = el.tag_end - (2 if el.self_closing else 1)
    while data[at - 1:at].isspace():       # before the spaces that precede '/>' or '>'
        at -= 1
    return at, at, f' {name}="{value}"'.encode()


def remove_attribute(data: bytes, el: Element, name: str) -> tuple[int, int, bytes] | None:
    """The edit that deletes attribute ``name`` (with the whitespace before it), or None."""
    found = _find_attribute(data, el, name)
    if found is None:
        return None
    return found.start(1), found.end(0), b""


def insert_first_child(data: bytes, el: Element, text: str) -> tuple[int, int, bytes]:
    """The edit that inserts the element text ``text`` as ``el``'s first child, on its own line
    indented like ``el``'s first child (or one step deeper than ``el``)."""
    line_start = data.rfind(b"\n", 0, el.start) + 1
    indent = data[line_start:el.start]
    indent = indent if indent.isspace() or not indent else b""
    after = data[el.tag_end:]
    lead = re.match(rb"[ \t]*\r?\n([ \t]*)<", after)
    child_indent = lead.group(1) if lead is not None else indent + b"  "
    newline = b"\r\n" if b"\r\n" in data[:el.tag_end + 2] else b"\n"
    return el.tag_end, el.tag_end, newline + child_indent + text.encode()


def apply(data: bytes, edits: list[tuple[int, int, bytes]]) -> bytes:
    """``data`` with the non-overlapping byte-range edits applied."""
    out, at = [], 0
    for start, end, text in sorted(edits, key=lambda e: (e[0], e[1])):
        if start < at:
            raise ValueError(f"overlapping edits at byte {start}")
        out += [data[at:start], text]
        at = end
    out.append(data[at:])
    return b"".join(out)
