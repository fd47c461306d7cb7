"""Every tutorial runs: the ```python blocks of each page, in order, in one namespace.

Pages: ``docs/tutorials/*.md``, ``docs/*.md`` and the README's quick tour. A page that reads the
real KUKA logs starts with ``<!-- requires: shared-data -->`` and is skipped, with the reason,
when ``../shared/data`` is absent. Blocks meant to be read, not run, are fenced ```text (output)
or ```bash (shell).
"""

from __future__ import annotations

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
    for number, block in enumerate(_blocks(page), start=1):
        try:
            exec(compile(block, f"{page.name}[block {number}]", "exec"), namespace)
        except Exception as exc:  # name the block: the traceback alone shows only <string>
            raise AssertionError(f"{page.name}, python block {number} failed: {exc!r}\n"
                                 f"{block}") from exc
