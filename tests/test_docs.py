"""Every tutorial runs: the ```python blocks of each page, in order, in one namespace.

Pages: ``docs/tutorials/*.md``, ``docs/*.md`` and the README's quick tour. A page that reads the
real KUKA logs starts with ``<!-- requires: shared-data -->`` and is skipped, with the reason,
when ``../shared/data`` is absent. Blocks meant to be read, not run, are fenced ```text (output)
or ```bash (shell); on a page marked ``<!-- output: checked -->`` a ```text block right after a
```python block must be what that block prints.
"""

from __future__ import annotations

import contextlib
import io
import re
from pathlib import Path

import matplotlib
import pytest

from .conftest import SHARED

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs").glob("*.md")) + sorted((ROOT / "docs" / "tutorials").glob("*.md"))
#: pages whose code takes more than a few seconds
SLOW = {"README.md", "tutorials/real_kuka.md", "real_kuka.md", "currents.md"}
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)
#: A page marked so has each ```text block that directly follows a ```python block compared
#: with what that block prints, line by line, ``…`` standing for any text.
CHECKED = "<!-- output: checked -->"
TEXT_AFTER = re.compile(r"\n\s*```text\n(.*?)^```", re.S | re.M)


def _blocks(page: Path) -> list[str]:
    return BLOCK.findall(page.read_text())


def _pages() -> list:
    out = []
    for page in [ROOT / "README.md", *PAGES]:
        if not _blocks(page):
            continue
        marks = [pytest.mark.slow] if page.name in SLOW else []
        out.append(pytest.param(page, id=str(page.relative_to(ROOT)), marks=marks))
    return out


def test_the_harness_finds_code():
    assert BLOCK.findall("text\n```python\nx = 1\n```\n```text\ny\n```\n") == ["x = 1\n"]
    assert any(_blocks(p) for p in PAGES)


@pytest.mark.parametrize("page", _pages())
def test_page_runs(page: Path, tmp_path, monkeypatch):
    text = page.read_text()
    if "<!-- requires: shared-data -->" in text and not (SHARED / "data").is_dir():
        pytest.skip(f"{page.name} reads the real logs in {SHARED / 'data'}, which is absent")
    matplotlib.use("Agg")
    # A page runs in a fresh folder beside a link to shared/, as the checkout does (pages say
    # "../shared/data/…"), with the examples at hand; the files it writes land there.
    work = tmp_path / "work"
    work.mkdir()
    (tmp_path / "shared").symlink_to(SHARED, target_is_directory=True)
    (work / "examples").symlink_to(ROOT / "examples", target_is_directory=True)
    monkeypatch.chdir(work)
    namespace: dict = {"__name__": f"docs_{page.stem}"}
    shown = {m.group(1): out.group(1) for m in BLOCK.finditer(text)
             if CHECKED in text and (out := TEXT_AFTER.match(text, m.end()))}
    for number, block in enumerate(_blocks(page), start=1):
        printed = io.StringIO()
        try:
            with contextlib.redirect_stdout(printed) if block in shown else \
                    contextlib.nullcontext():
                exec(compile(block, f"{page.name}[block {number}]", "exec"), namespace)
        except Exception as exc:  # name the block: the traceback alone shows only <string>
            raise AssertionError(f"{page.name}, python block {number} failed: {exc!r}\n"
                                 f"{block}") from exc
        if block in shown:
            _check_output(shown[block], printed.getvalue(), f"{page.name}[block {number}]")


def _check_output(shown: str, printed: str, where: str) -> None:
    """Each line of ``shown`` matches the printed line (``…`` stands for any text)."""
    expected, got = shown.rstrip("\n").splitlines(), printed.rstrip("\n").splitlines()
    assert len(expected) == len(got), f"{where} prints {len(got)} lines, the page shows " \
                                      f"{len(expected)}:\n{printed}"
    for want, line in zip(expected, got):
        pattern = ".*".join(re.escape(part) for part in want.split("…"))
        assert re.fullmatch(pattern, line), f"{where}: the page shows\n{want}\nthe code " \
                                            f"prints\n{line}"


def test_shown_output_is_matched_with_ellipses():
    page = "```python\nx\n```\n\nprose\n```python\ny\n```\n\n```text\nY\n```\n"
    assert [(m.group(1), bool(TEXT_AFTER.match(page, m.end()))) for m in BLOCK.finditer(page)] \
        == [("x\n", False), ("y\n", True)]
    _check_output("a /tmp/…/run: 3\n  - x […]\n", "a /tmp/xyz/run: 3\n  - x [1, 2]\n", "p")
    with pytest.raises(AssertionError, match="the page shows"):
        _check_output("  - not trimmed\n", "  - no trim requested\n", "p")
    with pytest.raises(AssertionError, match="prints 2 lines"):
        _check_output("a\n", "a\nb\n", "p")
