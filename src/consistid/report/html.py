"""One self-contained HTML page: headings, paragraphs, real ``<table>``s and embedded figures.

Every report of consistid (identification, diagnosis, …) is a :class:`Page`. The page has no
external resource: figures are PNG files embedded as ``data:image/png;base64`` URIs, the style
sheet is inline. Layout rules that keep everything on the page, whatever its width:

* ``img {max-width: 100%; height: auto}``: a figure shrinks with the page, never overflows;
* cells wrap long contents between words (a long base-parameter grouping wraps instead of
  widening its column) and break a word only when it alone is wider than the page
  (``overflow-wrap: break-word``, which, unlike ``anywhere``, never narrows a column below its
  longest word: no "coulo|mb"), numbers are right-aligned in a monospace font; a header
  breaks between words only, never inside one (``word-break: keep-all; overflow-wrap:
  normal; hyphens: none``), and each table sits in a ``div.cid-table`` that scrolls sideways
  when its columns need more than the page;
* the first box (:func:`findings_html`) says the worst finding first, then each further finding
  once (:func:`unique`);
* text (notes, verdicts) is HTML, never a ``<pre>`` block of fixed-width text.

The page is valid HTML5 that :mod:`html.parser` reads without error (tested), and the
``_repr_html_`` of a result is :meth:`Page.fragment` (no ``<html>`` wrapper) for Jupyter.
"""

from __future__ import annotations

import base64
import html
import io
import math
from pathlib import Path
from typing import Any, Iterable, Sequence

import numpy as np

from ..errors import OutputPathError
from ..filesafety import replacing

#: The inline style sheet (module docstring for the layout rules).
STYLE = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;max-width:1100px;
margin:0 auto;padding:0 16px 40px;color:#1d1d1f;line-height:1.45;box-sizing:border-box}
h1{font-size:1.6em;margin:.8em 0 .2em}h2{font-size:1.25em;margin:1.6em 0 .4em;
border-bottom:1px solid #ddd;padding-bottom:.2em}h3{font-size:1.05em;margin:1.2em 0 .3em}
.cid-report img{max-width:100%;height:auto;display:block;margin:.4em 0}
.cid-report figure{margin:1em 0;max-width:100%}
.cid-report figcaption{font-size:.88em;color:#555}
.cid-report table{border-collapse:collapse;max-width:100%;margin:.5em 0 1em;font-size:.86em}
.cid-report th,.cid-report td{border:1px solid #d4d4d4;padding:3px 7px;text-align:left;
vertical-align:top;overflow-wrap:break-word}
.cid-report th{background:#f2f2f2;word-break:keep-all;overflow-wrap:normal;hyphens:none}
.cid-report .cid-table{max-width:100%;overflow-x:auto}
.cid-report td.num{text-align:right;font-family:ui-monospace,Menlo,Consolas,monospace;
white-space:nowrap}
.cid-report td.key{white-space:nowrap;overflow-wrap:normal}
.cid-report tr.bad td{background:#fde8e8}.cid-report tr.good td{background:#fff}
.cid-report caption{caption-side:top;text-align:left;font-size:.9em;color:#444;padding:2px 0}
.cid-report .verdict{padding:8px 12px;border-left:4px solid #888;background:#f7f7f7}
.cid-report .verdict.ok{border-color:#2e8b57}.cid-report .verdict.warn{border-color:#d08000}
.cid-report .verdict.bad{border-color:#c0392b;background:#fdf1f0}
.cid-report .verdict.warn{background:#fdf7ec}
.cid-report .verdict .headline{font-weight:600;margin:.2em 0 .4em}
.cid-report .verdict ul{margin:.2em 0;padding-left:1.3em}
.cid-report code{font-size:.92em;background:#f4f4f4;padding:0 3px}
.cid-report pre{white-space:pre-wrap;overflow-wrap:anywhere;font-size:.85em;background:#f6f6f6;
padding:6px}
.cid-report details{margin:.5em 0}
"""


def esc(value: Any) -> str:
    """``value`` as escaped HTML text."""
    return html.escape(str(value), quote=True)


def fmt(value: Any, spec: str = ".4g") -> str:
    """A cell's text: floats with ``spec`` (``nan``/``inf`` spelled out), others ``str``."""
    if isinstance(value, (bool, np.bool_)):
        return "yes" if value else "no"
    if isinstance(value, (float, np.floating)):
        v = float(value)
        return format(v, spec) if math.isfinite(v) else str(v)
    return str(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def png_bytes(fig: Any, dpi: int = 100) -> bytes:
    """A matplotlib figure rendered as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def data_uri(png: bytes) -> str:
    """``data:image/png;base64,…`` of PNG bytes."""
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def table_html(header: Sequence[str], rows: Iterable[Sequence[Any]], *, caption: str = "",
               floatfmt: str = ".4g", row_classes: Sequence[str] | None = None,
               keys: Sequence[int] = (0,)) -> str:
    """A ``<table>``: a header row, then ``rows`` (numbers right-aligned, formatted with
    ``floatfmt``; a cell may be ``(value, spec)`` to format one number its own way). Text
    cells of the ``keys`` columns (names: the first by default) do not wrap; other text wraps
    between words. The table sits in a ``div.cid-table`` that scrolls sideways when its
    columns' longest words need more than the page."""
    out = ['<div class="cid-table"><table>']
    if caption:
        out.append(f"<caption>{esc(caption)}</caption>")
    if any(header):
        out.append("<thead><tr>" + "".join(f"<th>{esc(h)}</th>" for h in header)
                   + "</tr></thead>")
    out.append("<tbody>")
    for k, row in enumerate(rows):
        cls = f' class="{esc(row_classes[k])}"' if row_classes and row_classes[k] else ""
        cells = []
        for c, cell in enumerate(row):
            spec = floatfmt
            if isinstance(cell, tuple) and len(cell) == 2 and isinstance(cell[1], str):
                cell, spec = cell
            numeric = _is_number(cell)
            css = ' class="num"' if numeric else ' class="key"' if c in keys else ""
            cells.append(f"<td{css}>{esc(fmt(cell, spec))}</td>")
        out.append(f"<tr{cls}>" + "".join(cells) + "</tr>")
    out.append("</tbody></table></div>")
    return "".join(out)


def unique(texts: Iterable[str]) -> list[str]:
    """``texts`` without repeats (first occurrence kept, surrounding blanks ignored)."""
    seen: set[str] = set()
    out = []
    for text in texts:
        key = " ".join(str(text).split())
        if key and key not in seen:
            seen.add(key)
            out.append(str(text))
    return out


#: Order of the findings' levels, least to most severe.
LEVELS = ("ok", "warn", "bad")


def findings_html(findings: Sequence[tuple[str, str]], anchor: str = "findings") -> str:
    """The first box of a report: ``findings`` are ``(level, text)`` pairs (level in
    :data:`LEVELS`). The box takes the worst level; its headline is the first of the worst
    findings, the others follow as a list, most severe first, each text once."""
    if not findings:
        return ""
    rank = {level: k for k, level in enumerate(LEVELS)}
    ordered = sorted(findings, key=lambda f: -rank[f[0]])      # stable: keeps the given order
    texts = unique(text for _, text in ordered)
    level = ordered[0][0]
    rest = "".join(f"<li>{esc(t)}</li>" for t in texts[1:])
    return (f'<div class="verdict {level}" id="{esc(anchor)}"><p class="headline">'
            f"{esc(texts[0])}</p>" + (f"<ul>{rest}</ul>" if rest else "") + "</div>")


class Page:
    """An HTML report under construction; :meth:`render` gives the document.

    Examples
    --------
    >>> page = Page("consistid identification: panda")
    >>> page.heading("Parameters")
    >>> page.table(["name", "value"], [("panda_link1.m", 3.06)])
    >>> text = page.render()
    """

    def __init__(self, title: str, subtitle: str = "") -> None:
        self.title = title
        self.parts: list[str] = [f"<h1>{esc(title)}</h1>"]
        if subtitle:
            self.parts.append(f"<p>{esc(subtitle)}</p>")
        self.figures: dict[str, bytes] = {}

    # ------------------------------------------------------------------------- content
    def heading(self, text: str, level: int = 2, anchor: str = "") -> None:
        ident = f' id="{esc(anchor)}"' if anchor else ""
        self.parts.append(f"<h{level}{ident}>{esc(text)}</h{level}>")

    def paragraph(self, text: str, css: str = "") -> None:
        """A paragraph of plain text (escaped); ``css`` a class such as ``"verdict ok"``."""
        cls = f' class="{esc(css)}"' if css else ""
        self.parts.append(f"<p{cls}>{esc(text)}</p>")

    def raw(self, markup: str) -> None:
        """Markup the caller built (and escaped) itself."""
        self.parts.append(markup)

    def bullets(self, items: Iterable[str]) -> None:
        items = list(items)
        if items:
            self.parts.append("<ul>" + "".join(f"<li>{esc(i)}</li>" for i in items) + "</ul>")

    def table(self, header: Sequence[str], rows: Iterable[Sequence[Any]], *, caption: str = "",
              floatfmt: str = ".4g", row_classes: Sequence[str] | None = None,
              keys: Sequence[int] = (0,)) -> None:
        """A ``<table>`` (:func:`table_html`)."""
        self.parts.append(table_html(header, rows, caption=caption, floatfmt=floatfmt,
                                     row_classes=row_classes, keys=keys))

    def key_values(self, pairs: Iterable[tuple[str, Any]], caption: str = "") -> None:
        """A two-column table of named figures (the names never break inside a word)."""
        self.table(["", ""], [(k, v) for k, v in pairs], caption=caption, keys=(0,))

    def figure(self, name: str, fig: Any, caption: str = "", dpi: int = 100) -> None:
        """Embed a matplotlib figure as PNG (kept in :attr:`figures` under ``name`` so that a
        report folder can also hold the PNG files)."""
        png = png_bytes(fig, dpi)
        self.figures[name] = png
        cap = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
        self.parts.append(f'<figure><img alt="{esc(caption or name)}" src="{data_uri(png)}"/>'
                          f"{cap}</figure>")

    # ------------------------------------------------------------------------- output
    def fragment(self) -> str:
        """The body as a ``<div>`` with its style (for Jupyter's ``_repr_html_``)."""
        return (f"<div class=\"cid-report\"><style>{STYLE}</style>" + "\n".join(self.parts)
                + "</div>")

    def render(self) -> str:
        """The whole self-contained document."""
        return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
                f"<title>{esc(self.title)}</title><style>{STYLE}</style></head>\n"
                "<body class=\"cid-report\">\n" + "\n".join(self.parts) + "\n</body></html>\n")

    def write(self, path: str | Path, text: str | None = None) -> Path:
        """Write the page: ``*.html`` (one file), or a folder holding ``report.html``, the
        figures as PNG files and, when ``text`` is given, ``report.txt``. Returns the path of
        the HTML file."""
        path = Path(path)
        if path.suffix.lower() in (".html", ".htm"):
            with replacing(path) as tmp:        # never a half-written page
                tmp.write_text(self.render(), encoding="utf-8")
            return path
        if "\0" in str(path):
            raise OutputPathError(f"report path {str(path)[:120]!r} holds a NUL character")
        if path.exists() and not path.is_dir():
            raise OutputPathError(f"report {str(path)!r} is an existing file and not .html: a "
                                  "report that is not one .html file is a folder of files; "
                                  "give a .html path or a folder")
        path.mkdir(parents=True, exist_ok=True)
        for name, png in self.figures.items():
            (path / f"{name}.png").write_bytes(png)
        if text is not None:
            (path / "report.txt").write_text(text, encoding="utf-8")
        out = path / "report.html"
        with replacing(out) as tmp:
            tmp.write_text(self.render(), encoding="utf-8")
        return out
