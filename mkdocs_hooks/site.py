"""mkdocs hooks for the docs site (``hooks:`` in mkdocs.yml).

* Markdown pages get the same reST-role and math rewrite as the docstrings
  (:mod:`rst_docstrings`, the griffe extension), so no page shows raw ``:func:`` markup.
* ``api/index.md``'s marker ``<!-- public-api -->`` becomes the table of the names
  ``import consistid`` offers (``consistid._EXPORTS``, in its order: the public API first), each
  with the first line of its docstring and a link to its full entry.
* A subpackage page (``::: consistid.<package>``) opens with the top-level names that package
  defines, before its modules.
* MathJax is served from the site itself (``js/mathjax/``), copied from the pip package
  ``django-static-mathjax`` (MathJax 3.2.2's build as released, Apache-2.0; it needs no Django)
  of the ``docs`` extra: the combined TeX → CommonHTML script, its fonts and the TeX extensions
  it loads on demand, so that the site renders its equations offline.
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


#: What the site serves of MathJax's ``es5`` build (:data:`MATHJAX_DIR` in the site).
MATHJAX_PARTS = ("tex-mml-chtml.js", "output/chtml/fonts/woff-v2", "input/tex/extensions")
MATHJAX_DIR = "js/mathjax"


def _mathjax_build() -> Path:
    """The ``es5`` folder of the installed MathJax package."""
    try:
        import mathjax                 # the django-static-mathjax distribution's package
    except ImportError:
        raise SystemExit("the docs site serves MathJax itself: pip install \"consistid[docs]\" "
                         "(it brings django-static-mathjax, MathJax's release files)") from None
    return Path(mathjax.__file__).parent / "static" / "mathjax" / "es5"


def on_files(files: Any, config: Any, **kwargs: Any) -> Any:
    from mkdocs.structure.files import File

    build = _mathjax_build()
    for part in MATHJAX_PARTS:
        found = [build / part] if (build / part).is_file() else sorted(
            f for f in (build / part).rglob("*") if f.is_file())
        for path in found:
            uri = f"{MATHJAX_DIR}/{path.relative_to(build).as_posix()}"
            files.append(File.generated(config, uri, abs_src_path=str(path)))
    return files

