"""mkdocs hooks for the docs site (``hooks:`` in mkdocs.yml).

* Markdown pages get the same reST-role and math rewrite as the docstrings
  (:mod:`rst_docstrings`, the griffe extension), so no page shows raw ``:func:`` markup.
* ``api/index.md``'s marker ``<!-- public-api -->`` becomes the table of the names
  ``import consistid`` offers (``consistid._EXPORTS``, in its order: the public API first), each
  with the first line of its docstring and a link to its full entry.
* A subpackage page (``::: consistid.<package>``) opens with the top-level names that package
  defines, before its modules.
"""

from __future__ import annotations

import importlib
import inspect
import re
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).parent))
from rst_docstrings import ROLE, convert_math, _role  # noqa: E402

MARKER = "<!-- public-api -->"
SUBPACKAGE = re.compile(r"^::: consistid\.(\w+)\s*$", re.M)


def _summary(obj: Any) -> str:
    doc = inspect.getdoc(obj) or ""
    first = doc.split("\n\n", 1)[0].replace("\n", " ").strip()
    return ROLE.sub(_role, first).replace("|", "\\|")


def public_api_table(package: str = "") -> str:
    """The Markdown table of ``consistid``'s top-level names (module docstring); with
    ``package``, only those it defines."""
    import consistid

    rows = ["| name | what it is |", "| --- | --- |"]
    for name, module in consistid._EXPORTS.items():
        if package and module.split(".")[0] != package:
            continue
        full = f"consistid.{module}"
        obj = getattr(importlib.import_module(full), name)
        rows.append(f'| <autoref identifier="{full}.{name}" optional><code>ci.{name}</code>'
                    f"</autoref> | {_summary(obj)} |")
    return "\n".join(rows)


def on_page_markdown(markdown: str, page: Any, **kwargs: Any) -> str:
    if MARKER in markdown:
        markdown = markdown.replace(MARKER, public_api_table())
    found = SUBPACKAGE.search(markdown)
    if found:
        table = public_api_table(found.group(1))
        if table.count("\n") > 1:
            markdown = (markdown[:found.start()] + "Its names at the top level of `consistid`:\n\n"
                        + table + "\n\n" + markdown[found.start():])
    return ROLE.sub(_role, convert_math(markdown))
