"""HTML reports (identification, diagnosis, demo): valid, self-contained, nothing wider than the
page — checked by parsing, and in a headless Chromium where one is installed."""

from __future__ import annotations

import base64
import html
import json
import re
import shutil
import struct
import subprocess
import warnings
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

import consistid as ci
from consistid.cli.commands import main
from consistid.report.html import Page
from consistid.simulate import Effects, record

VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source",
        "track", "wbr"}
CHROMIUM = next((p for p in ("/usr/bin/chromium", "/usr/bin/chromium-browser",
                             shutil.which("chromium") or "", shutil.which("google-chrome") or "")
                 if p and Path(p).is_file()), None)


class Checker(HTMLParser):
    """Every element closed in order, images and tables collected."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.images: list[dict[str, str]] = []
        self.tables = self.pres = 0
        self.table_rows: list[int] = []

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.images.append(dict(attrs))
        if tag == "table":
            self.tables += 1
            self.table_rows.append(0)
        if tag == "tr" and self.table_rows:
            self.table_rows[-1] += 1
        if tag == "pre":
            self.pres += 1
        if tag not in VOID:
            self.stack.append(tag)

    def handle_startendtag(self, tag, attrs):
        if tag == "img":
            self.images.append(dict(attrs))

    def handle_endtag(self, tag):
        if tag in VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()


def check_html(text: str, n_images: int | None = None) -> Checker:
    """Parses cleanly; every <img> is an embedded PNG no wider than 1000 px."""
    assert text.startswith("<!DOCTYPE html>")
    checker = Checker()
    checker.feed(text)
    checker.close()
    assert checker.errors == [] and checker.stack == [], (checker.errors, checker.stack)
    assert "src=\"http" not in text and "href=\"http" not in text     # self-contained
    for img in checker.images:
        src = img.get("src", "")
        assert src.startswith("data:image/png;base64,"), src[:40]
        png = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        width, height = struct.unpack(">II", png[16:24])
        assert 0 < width <= 1000 and height > 0, (width, height)
        assert img.get("alt")
    if n_images is not None:
        assert len(checker.images) == n_images
    return checker


# ------------------------------------------------------------------ fixtures
@pytest.fixture(scope="module")
def ur5_reports(tmp_path_factory):
    """An SDP identification of a UR5 (torques from pin.rnea + friction + noise) and its
    report with training and held-out data."""
    model = ci.RobotModel.example("ur5")
    rng = np.random.default_rng(0)

    def data(n, seed):
        r = np.random.default_rng(seed)
        t = np.arange(n) / 200.0
        w = r.uniform(0.3, 1.2, 6)
        q = 0.8 * np.sin(np.outer(t, w) + r.uniform(0, 6, 6))
        dq, ddq = 0.8 * w * np.cos(np.outer(t, w)), -0.8 * w ** 2 * np.sin(np.outer(t, w))
        tau = model.rnea(q, dq, ddq) + 0.6 * np.sign(dq) + 0.2 * dq
        return ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=tau + 0.05 * rng.normal(size=tau.shape))

    train, held = data(1200, 1), data(400, 2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, train)
    folder = tmp_path_factory.mktemp("reports")
    return res, train, held, res.report(folder / "identify.html", data=train, held_out=held)


@pytest.fixture(scope="module")
def diagnosis_report(tmp_path_factory):
    model = ci.RobotModel.example("ur5")
    traj = ci.FourierTrajectory.random(model, harmonics=4, period=10.0, seed=0)
    rec = record(model, traj, Effects(coulomb=1.0, torque_noise=0.05), duration=16.0, rate=200.0)
    diag = ci.diagnose(model, ci.Dataset.from_recording(rec.t, rec.q, rec.tau))
    return diag, diag.report(tmp_path_factory.mktemp("diag") / "diagnosis.html")


@pytest.fixture(scope="module")
def demo_report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("demo") / "out"
    assert main(["-q", "demo", "--robot", "ur5", "--duration", "6", "--rate", "200",
                 "--output", str(folder)]) == 0
    return folder / "report.html"


# ------------------------------------------------------------------ parsing
def test_identification_report_is_real_html(ur5_reports):
    res, _, _, path = ur5_reports
    # torque, residual over time, histogram, spectrum × 2 sets, and the parameters' error bars
    page = check_html(path.read_text(), n_images=9)
    assert page.pres == 0 or "configuration" in path.read_text()
    text = path.read_text()
    # the base-parameter table has one row per base parameter (+ header)
    assert res.base.n_base + 1 in page.table_rows
    assert "A name marked *" in text
    # every body's margin is in the body table, with the pseudo-inertia's smallest eigenvalue
    for check in res.consistency.bodies:
        assert f">{check.body}</td>" in text
        assert format(check.min_pseudo_inertia_eigenvalue, ".4g") in text
    assert "held-out RMS [N·m]" in text
    assert res.solver.status in text


def test_report_folder_and_text(ur5_reports, tmp_path):
    res, train, held, _ = ur5_reports
    folder = res.report(tmp_path / "rep", data=train)
    names = {p.name for p in folder.iterdir()}
    assert {"report.html", "report.txt", "torque_train.png", "histogram_train.png",
            "spectrum_train.png", "residual_train.png", "parameters.png"} <= names
    assert res.report(tmp_path / "r.txt").read_text().startswith("consistid identification")
    assert res.report() == res.summary()
    # without data: only the parameters against the prior
    check_html(res.report(tmp_path / "plain.html").read_text(), n_images=1)


def test_repr_html_is_a_fragment(ur5_reports):
    res, _, _, _ = ur5_reports
    fragment = res._repr_html_()
    assert fragment.startswith('<div class="cid-report">') and "<img" not in fragment
    checker = Checker()
    checker.feed(fragment)
    assert checker.errors == [] and checker.stack == [] and checker.tables >= 3


def test_diagnosis_report_is_real_html(diagnosis_report):
    diag, path = diagnosis_report
    text = path.read_text()
    page = check_html(text, n_images=3)
    assert page.pres == 0 and page.tables >= 5
    for effect in diag.effects:
        assert f">{effect.name}</td>" in text
    if getattr(diag, "remainder", None) is not None:
        assert "Unexplained remainder" in text
    first_box = text[text.index('<div class="verdict'):text.index("</div>")]
    for note in diag.notes:                  # each note once, in the first box
        assert text.count(html.escape(note, quote=True)) == 1 and html.escape(note) in first_box


def test_cells_are_escaped():
    page = Page("a <b> & c")
    page.table(["x<y"], [["<script>alert(1)</script>"]])
    text = page.render()
    assert "<script>alert" not in text and "&lt;script&gt;" in text
    check_html(text)


def test_demo_writes_a_report(demo_report):
    check_html(demo_report.read_text(), n_images=9)
    assert (demo_report.parent / "result.json").is_file()


# ------------------------------------------------------------------ headless browser
PROBE = """<script>
window.addEventListener('load', () => {
  const W = document.documentElement.clientWidth;
  const bad = [];
  for (const el of document.querySelectorAll('img, .cid-table')) {
    const r = el.getBoundingClientRect();
    if (r.right > W + 0.5 || r.left < -0.5) bad.push(el.tagName + ' ' + Math.round(r.width));
  }
  const broken = [...document.images].filter(i => !i.complete || i.naturalWidth === 0).length;
  document.body.setAttribute('data-probe', JSON.stringify({W: W, bad: bad, broken: broken,
    n: document.querySelectorAll('img, .cid-table').length,
    scroll: document.documentElement.scrollWidth}));
});
</script>"""


def _probe(path: Path, width: int, tmp_path: Path, screenshot: bool = False) -> dict:
    probe = tmp_path / f"probe_{width}_{path.name}"
    probe.write_text(path.read_text().replace("</body>", PROBE + "</body>"))
    args = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars",
            f"--window-size={width},1600", "--virtual-time-budget=8000"]
    out = subprocess.run([*args, "--dump-dom", probe.as_uri()], capture_output=True,
                         text=True, timeout=120).stdout
    found = re.search(r'data-probe="([^"]*)"', out)
    assert found, out[-500:]
    if screenshot:
        shot = tmp_path / f"shot_{width}_{path.stem}.png"
        subprocess.run([*args, f"--screenshot={shot}", path.as_uri()], capture_output=True,
                       timeout=120)
        assert shot.is_file() and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    return json.loads(found.group(1).replace("&quot;", '"'))


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium installed (apt-get install chromium)")
@pytest.mark.parametrize("width", [1280, 720])
def test_nothing_wider_than_the_page_in_chromium(ur5_reports, diagnosis_report, demo_report,
                                                 width, tmp_path):
    """Screenshots of the identification, diagnosis and demo reports: every image and table
    (its sideways-scrolling box) lies inside the page's width, every image decodes, the page
    does not scroll sideways."""
    for path in (ur5_reports[3], diagnosis_report[1], demo_report):
        probe = _probe(path, width, tmp_path, screenshot=path == demo_report)
        assert probe["n"] > 5, path
        assert probe["bad"] == [] and probe["broken"] == 0, (path.name, probe)
        assert probe["scroll"] <= probe["W"], (path.name, probe)


def test_diagnosis_repr_html_and_progress(diagnosis_report):
    diag, _ = diagnosis_report
    fragment = diag._repr_html_()
    assert fragment.startswith('<div class="cid-report">') and "<img" not in fragment
    checker = Checker()
    checker.feed(fragment)
    assert checker.errors == [] and checker.stack == [] and checker.tables >= 4


def test_any_standard_parameter_answer_has_an_html_view(planar_2r):
    """A recovery (base coefficients → consistent standard parameters) shows its bodies'
    margins as a table in Jupyter."""
    base = ci.compute_base_parameters(planar_2r)
    rec = ci.recover_standard(planar_2r, base.project(planar_2r.prior_parameters),
                              friction=None)
    fragment = rec._repr_html_()
    checker = Checker()
    checker.feed(fragment)
    assert checker.errors == [] and checker.stack == [] and checker.tables == 1
    assert checker.table_rows == [1 + planar_2r.n_bodies]
    for check in rec.consistency.bodies:
        assert f">{check.body}</td>" in fragment
