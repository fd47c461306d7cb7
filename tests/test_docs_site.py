"""The docs site builds (``mkdocs build --strict``) and renders: no raw reST roles or
``.. math::`` directives in the built pages, math marked for MathJax, only types in the API
tables' "Type" column, the nav in the order a user learns, every top-level name on the API
page, and (in a headless Chromium, where one is installed) no code block wider than its box.

The build takes about 20 s on a 2-core machine, hence ``slow``.
"""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
NEEDED = ("mkdocs", "material", "mkdocstrings", "mkdocstrings_handlers.python")
MISSING = [m for m in NEEDED if importlib.util.find_spec(m.split(".")[0]) is None]
RAW = (":mod:", ":func:", ":class:", ":meth:", ":attr:", ":data:", ":math:", ".. math::")
#: the nav's top level, in the order a user learns
NAV = ["Home", "Concepts", "Tutorials", "Diagnosis", "API", "Architecture", "Benchmarks"]
#: a "Type" cell holding one of these words, or ending with a full stop, is a description
ENGLISH = re.compile(r"\b(the|a|an|to|for|is|are|in|on|with|from|when|if|each|this|that|not|"
                     r"by|its|be|which)\b", re.IGNORECASE)
CHROMIUM = next((p for p in ("/usr/bin/chromium", "/usr/bin/chromium-browser")
                 if Path(p).is_file()), None)

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(bool(MISSING), reason=f"docs extra not installed: {MISSING}")]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT / "src"), os.environ.get("PYTHONPATH", "")]), "NO_MKDOCS_2_WARNING": "1"}
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d",
                          str(out)], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    return out


def _pages(site: Path) -> list[Path]:
    return sorted(site.rglob("*.html"))


class Tables(HTMLParser):
    """Every table's rows as lists of cell texts."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: list[list[list[str]]] = []
        self.cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self.tables.append([])
        elif tag == "tr" and self.tables:
            self.tables[-1].append([])
        elif tag in ("td", "th") and self.tables and self.tables[-1]:
            self.cell = []
            self.tables[-1][-1].append("")

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self.cell is not None:
            self.tables[-1][-1][-1] = " ".join("".join(self.cell).split())
            self.cell = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell.append(data)


def test_no_raw_rest_markup(site):
    found = []
    for page in _pages(site):
        text = page.read_text(encoding="utf-8")
        for raw in RAW:
            k = text.find(raw)
            if k >= 0:
                found.append(f"{page.relative_to(site)}: {text[max(0, k - 60):k + 60]!r}")
    assert not found, "\n".join(found[:20])


def test_no_raw_rest_table(site):
    """A reST simple table in a docstring (``consistid.data``'s module map, the logger presets)
    becomes an HTML table, not lines of ``=====`` borders."""
    border = re.compile(r"={5,}[ \t]+={5,}")
    found = [str(page.relative_to(site)) for page in _pages(site)
             if border.search(page.read_text(encoding="utf-8"))]
    assert not found, found
    data = Tables()
    data.feed((site / "api" / "data" / "index.html").read_text(encoding="utf-8"))
    assert any(t and t[0][:2] == ["module", "holds"] and len(t) >= 10 for t in data.tables)


def test_math_is_marked_for_mathjax(site):
    page = (site / "api" / "identification" / "index.html").read_text(encoding="utf-8")
    assert page.count('class="arithmatex"') >= 5      # from the docstrings' .. math:: blocks
    index = (site / "index.html").read_text(encoding="utf-8")
    assert "mathjax" in index.lower()


def test_mathjax_is_served_by_the_site(site):
    """Every script a page loads is a file of the site (no CDN): MathJax, its fonts and the
    TeX extensions it loads on demand are copied in by the build."""
    index = (site / "concepts" / "index.html")
    sources = re.findall(r'<script[^>]* src="([^"]+)"', index.read_text(encoding="utf-8"))
    assert any(src.endswith("mathjax/tex-mml-chtml.js") for src in sources), sources
    for src in sources:
        assert "://" not in src and (index.parent / src).resolve().is_file(), src
    fonts = site / "js" / "mathjax" / "output" / "chtml" / "fonts" / "woff-v2"
    assert len(list(fonts.glob("*.woff"))) > 10
    assert (site / "js" / "mathjax" / "input" / "tex" / "extensions" / "physics.js").is_file()


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium at /usr/bin/chromium")
def test_math_renders_offline(site, tmp_path):
    """In a headless Chromium with no network, MathJax typesets every marked equation of the
    concepts page, without an error."""
    page = site / "concepts" / "index.html"
    marked = page.read_text(encoding="utf-8").count('class="arithmatex"')
    out = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
                          "--disable-background-networking", "--disable-component-update",
                          "--disable-sync", "--no-first-run", f"--user-data-dir={tmp_path}",
                          "--virtual-time-budget=8000", "--dump-dom", page.as_uri()],
                         capture_output=True, text=True, timeout=120).stdout
    assert marked > 0 and out.count("<mjx-container") >= marked, out[-500:]
    assert "<mjx-merror" not in out


def test_type_column_holds_types(site):
    bad = []
    for page in (site / "api").rglob("*.html"):
        parser = Tables()
        parser.feed(page.read_text(encoding="utf-8"))
        for table in parser.tables:
            if not table or "Type" not in table[0]:
                continue
            k = table[0].index("Type")
            for row in table[1:]:
                cell = row[k] if k < len(row) else ""
                words = [w for w in cell.split() if w != "|"]
                if ENGLISH.search(cell) or cell.endswith(".") or len(words) > 5:
                    bad.append(f"{page.parent.name}: {row[0]!r} has type {cell[:70]!r}")
    assert not bad, "\n".join(bad[:20])


def test_nav_in_learning_order(site):
    text = (site / "index.html").read_text(encoding="utf-8")
    nav = text[text.index('md-nav--primary'):]
    labels = re.findall(r'class="md-nav__link[^"]*"[^>]*>\s*(?:<span[^>]*>)?\s*([^<]+?)\s*<', nav)
    top = [label for label in NAV if label in labels]
    assert top == NAV, labels[:40]
    assert [labels.index(label) for label in NAV] == sorted(labels.index(label) for label in NAV)
    assert "Real KUKA" in labels and "Api" not in labels and "Real kuka" not in labels
    tutorials = labels[labels.index("Tutorials") + 1:labels.index("Diagnosis")]
    assert tutorials[0] == "From a robot's log" and tutorials != sorted(tutorials)


def test_api_page_lists_the_public_names_first(site):
    import consistid

    page = (site / "api" / "index.html").read_text(encoding="utf-8")
    positions = [page.find(f"ci.{name}<") for name in consistid._EXPORTS]
    assert min(positions) > 0, [n for n, p in zip(consistid._EXPORTS, positions) if p < 0]
    assert positions == sorted(positions)
    sub = (site / "api" / "identification" / "index.html").read_text(encoding="utf-8")
    first_module = sub.find('id="consistid.identification.base"')
    assert 0 < sub.find("ci.identify<") < first_module         # its public names before its modules


PROBE = """<script>
window.addEventListener('load', () => {
  const bad = [...document.querySelectorAll('pre > code')]
    .filter(c => c.scrollWidth > c.clientWidth + 1).map(c => c.textContent.slice(0, 40));
  document.body.setAttribute('data-probe', JSON.stringify({n: document.querySelectorAll(
    'pre > code').length, bad: bad}));
});
</script>"""


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium at /usr/bin/chromium")
@pytest.mark.parametrize("width", [1280, 720])
def test_code_blocks_not_clipped(site, width, tmp_path):
    """Tutorial code blocks fit their box at 1280 and 720 px (they wrap)."""
    for name in ("real_kuka", "logs"):
        page = site / "tutorials" / name / "index.html"
        probe = page.with_name(f"probe_{width}.html")
        probe.write_text(page.read_text(encoding="utf-8").replace("</body>", PROBE + "</body>"),
                         encoding="utf-8")
        profile = tmp_path / f"profile_{name}"
        out = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
                              "--disable-background-networking", "--disable-component-update",
                              "--disable-sync", "--no-first-run", f"--user-data-dir={profile}",
                              f"--window-size={width},1600", "--virtual-time-budget=5000",
                              "--dump-dom", probe.as_uri()],
                             capture_output=True, text=True, timeout=120).stdout
        shutil.rmtree(profile, ignore_errors=True)
        found = re.search(r'data-probe="([^"]*)"', out)
        assert found, out[-500:]
        result = json.loads(found.group(1).replace("&quot;", '"'))
        assert result["n"] > 3 and result["bad"] == [], (name, width, result)
