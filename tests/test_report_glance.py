"""Reports read at a glance: the first box names the worst finding, every warning once and near
the top, measured and predicted told apart, residual-over-time and parameter plots, and a word on
why each residual histogram sits inside or outside the noise curve — checked by parsing the HTML,
and at 720 and 1280 px in a headless Chromium where one is installed (table headers never break
inside a word).

Torques are the rigid-body torques of Pinocchio's RNEA plus friction and noise (independent of
the identification code); the "poor" case adds a disturbance the regressor cannot model and
predicts motion wider than the training data.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import warnings
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import consistid as ci
from consistid.identification.report import BAD_FIT, POOR_FIT, SPREAD_BAND
from consistid.report.html import LEVELS, findings_html

CHROMIUM = "/usr/bin/chromium" if Path("/usr/bin/chromium").is_file() else None


def _data(model, n, seed, amplitude=0.8, disturbance=0.0, noise=0.05):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 200.0
    w = rng.uniform(0.3, 1.2, model.nv)
    phase = rng.uniform(0, 6, model.nv)
    q = amplitude * np.sin(np.outer(t, w) + phase)
    dq = amplitude * w * np.cos(np.outer(t, w) + phase)
    ddq = -amplitude * w ** 2 * np.sin(np.outer(t, w) + phase)
    tau = model.rnea(q, dq, ddq) + 0.6 * np.sign(dq) + 0.2 * dq
    tau += disturbance * np.sin(3.0 * t)[:, None] + noise * rng.normal(size=tau.shape)
    return ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=tau)


def _report(model, train, held, path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, train)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res.report(path, data=train, held_out=held)
    return res, path.read_text(encoding="utf-8"), caught


@pytest.fixture(scope="module")
def poor(tmp_path_factory):
    """A UR5 fit with an unmodelled disturbance, predicted on wider motion."""
    model = ci.RobotModel.example("ur5")
    train = _data(model, 1200, 1, disturbance=0.3)
    held = _data(model, 400, 2, amplitude=1.2, disturbance=0.3)
    return (model, train, held,
            *_report(model, train, held, tmp_path_factory.mktemp("poor") / "poor.html"))


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    """A Panda fit whose model holds (friction modelled, tiny noise), held out on the same
    kind of motion."""
    model = ci.RobotModel.example("panda")
    train = _data(model, 1500, 3, noise=0.002)
    held = _data(model, 500, 4, noise=0.002, amplitude=0.7)
    return (model, train, held,
            *_report(model, train, held, tmp_path_factory.mktemp("clean") / "clean.html"))


@pytest.fixture(scope="module")
def one_way(tmp_path_factory):
    """A UR5 whose wrist_3 moves one way only: its Coulomb and offset are one column (the SDP's
    prior splits them: an uninformed and a weakly informed direction)."""
    model = ci.RobotModel.example("ur5")
    train = _data(model, 1000, 5)
    t = train.t
    q, dq, ddq = train.q.copy(), train.dq.copy(), train.ddq.copy()
    q[:, 5], dq[:, 5], ddq[:, 5] = 0.3 * t - 0.1 * np.cos(t), 0.3 + 0.1 * np.sin(t), 0.1 * np.cos(t)
    tau = model.rnea(q, dq, ddq) + 0.6 * np.sign(dq) + 0.2 * dq
    train = ci.Dataset(t=t, q=q, dq=dq, ddq=ddq, tau=tau + 0.05 * np.random.default_rng(6)
                       .normal(size=tau.shape))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = ci.identify(model, train)
    path = res.report(tmp_path_factory.mktemp("oneway") / "one_way.html")
    return model, train, None, res, path.read_text(encoding="utf-8"), []


class Page(HTMLParser):
    """The first box (class ``verdict``: headline and items), text blocks, image alts, tables."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.box: dict | None = None
        self.in_box = 0
        self.blocks: list[str] = []          # the text of each <p> and <li>
        self.current: list[str] | None = None
        self.alts: list[str] = []
        self.first_h2_seen = False
        self.box_before_h2 = False
        self.rows: list[list[str]] = []
        self.cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "div" and "verdict" in (attrs.get("class") or "") and self.box is None:
            self.box = {"class": attrs["class"], "items": []}
            self.box_before_h2 = not self.first_h2_seen
            self.in_box = 1
        elif tag == "div" and self.in_box:
            self.in_box += 1
        if tag == "h2":
            self.first_h2_seen = True
        if tag in ("p", "li"):
            self.current = []
        if tag == "img":
            self.alts.append(attrs.get("alt", ""))
        if tag == "tr":
            self.rows.append([])
        if tag in ("td", "th"):
            self.cell = []

    def handle_endtag(self, tag):
        if tag in ("p", "li") and self.current is not None:
            text = " ".join("".join(self.current).split())
            self.blocks.append(text)
            if self.in_box:
                self.box["items"].append(text)
            self.current = None
        if tag == "div" and self.in_box:
            self.in_box -= 1
        if tag in ("td", "th") and self.cell is not None:
            self.rows[-1].append(" ".join("".join(self.cell).split()))
            self.cell = None

    def handle_data(self, data):
        if self.current is not None:
            self.current.append(data)
        if self.cell is not None:
            self.cell.append(data)


def _parse(text: str) -> Page:
    page = Page()
    page.feed(text)
    return page


def _relative_error(res, data):
    tau = data.require_torque()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = tau - res.predict(data)
    return np.linalg.norm(r, axis=0) / np.linalg.norm(tau, axis=0)


def test_first_box_names_the_worst_joint(poor):
    model, _, held, res, text, _ = poor
    rel = _relative_error(res, held)
    worst = model.joint_names[int(np.argmax(rel))]
    assert rel.max() > POOR_FIT                      # the case is what it claims to be
    page = _parse(text)
    assert page.box is not None and page.box_before_h2
    tau = held.require_torque()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rms = np.sqrt(np.mean((tau - res.predict(held)) ** 2, axis=0))
    j = int(np.argmax(rel))
    above_noise = rms[j] / res.sigma[j] > SPREAD_BAND[1]
    assert page.box["class"].split()[-1] == ("bad" if rel[j] > BAD_FIT and above_noise
                                             else "warn")
    headline = page.box["items"][0]
    assert f"Poorly predicted joint {worst}:" in headline
    assert f"{100 * rel.max():.1f} %" in headline
    others = [n for n, r in zip(model.joint_names, rel) if r > POOR_FIT and n != worst]
    for name in others:
        assert any(name in item for item in page.box["items"][1:]), name


def test_a_good_fit_names_no_poor_joint(clean):
    model, _, held, res, text, _ = clean
    rel = _relative_error(res, held)
    page = _parse(text)
    box = " ".join(page.box["items"])
    flagged = [n for n, r in zip(model.joint_names, rel) if r > POOR_FIT]
    if flagged:                 # a small torque against its noise can still cross the line
        worst = model.joint_names[int(np.argmax(rel))]
        assert f"Poorly predicted joint {worst}:" in page.box["items"][0]
    else:
        assert "Poorly predicted" not in box
    assert rel.max() < 5 * POOR_FIT


def test_each_warning_once_and_in_the_first_box(poor):
    _, _, _, _, text, caught = poor
    page = _parse(text)
    messages = {str(w.message) for w in caught}
    assert any("training data never went" in m for m in messages)   # extrapolation was warned
    assert len(caught) == len(messages)                              # the caller saw each once
    for message in messages:
        assert sum(message in block for block in page.blocks) == 1, message
        assert any(message in item for item in page.box["items"]), message
    repeated = [b for b in set(page.blocks) if b and page.blocks.count(b) > 1]
    assert repeated == []


@pytest.mark.parametrize("case", ["poor", "clean", "one_way"])
def test_weak_and_uninformed_directions_are_in_the_first_box(case, request):
    """Whatever the case, each direction the data barely or do not inform is named in the first
    box (the first three / four), and the box is not green then."""
    res, text = request.getfixturevalue(case)[3:5]
    if case == "one_way":                    # the case is what it claims to be
        assert any("wrist_3_joint" in w for w in res.weakly_informed) and res.uninformed
    page = _parse(text)
    box = " ".join(page.box["items"])
    for names, shown in ((res.weakly_informed, 3), (res.uninformed, 4)):
        for name in names[:shown]:
            assert name in box, (name, box[:300])
    if res.weakly_informed or res.uninformed:
        assert page.box["class"].split()[-1] != "ok"


def test_the_plots_exist(poor, clean):
    for case in (poor, clean):
        alts = _parse(case[4]).alts
        for label in ("train", "held-out"):
            assert any(a.startswith(f"{label} data: measured (thin black) and predicted "
                                    "(dashed orange)") for a in alts), alts
            assert any(a.startswith(f"{label} residual τ − τ̂ over time") for a in alts)
        assert any(a.startswith("base parameters: estimate ± 2σ") for a in alts)


def test_histogram_reading_matches_the_spread(poor):
    model, _, held, res, text, _ = poor
    page = _parse(text)
    tau = held.require_torque()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rms = np.sqrt(np.mean((tau - res.predict(held)) ** 2, axis=0))
    rows = [r for r in page.rows if len(r) == 5 and r[0] in model.joint_names]
    held_rows = rows[len(model.joint_names):]          # the train table comes first
    assert len(held_rows) == model.nv
    for j, row in enumerate(held_rows):
        ratio = rms[j] / res.sigma[j]
        assert float(row[1]) == pytest.approx(rms[j], rel=1e-3)
        word = ("inside" if ratio < SPREAD_BAND[0] else "on" if ratio <= SPREAD_BAND[1]
                else "outside")
        assert row[4].startswith(f"{word} the curve"), (row, ratio)


PROBE = """<script>
window.addEventListener('load', () => {
  const W = document.documentElement.clientWidth;
  const broken = [];
  for (const th of document.querySelectorAll('th, td:first-child')) {
    const walker = document.createTreeWalker(th, NodeFilter.SHOW_TEXT);
    for (let node = walker.nextNode(); node; node = walker.nextNode()) {
      const re = /[^\\s-]+/g;           // a break after a hyphen is a break between parts
      let m;
      while ((m = re.exec(node.data)) !== null) {
        const range = document.createRange();
        range.setStart(node, m.index);
        range.setEnd(node, m.index + m[0].length);
        const tops = new Set([...range.getClientRects()].map(r => Math.round(r.top)));
        if (tops.size > 1) broken.push(m[0]);
      }
    }
  }
  const box = document.querySelector('.verdict').getBoundingClientRect();
  const wide = [...document.querySelectorAll('img, .cid-table')]
    .filter(e => e.getBoundingClientRect().right > W + 0.5).length;
  document.body.setAttribute('data-probe', JSON.stringify({broken: broken, boxTop: box.top,
    wide: wide, scroll: document.documentElement.scrollWidth, W: W}));
});
</script>"""


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium at /usr/bin/chromium "
                                             "(apt-get install chromium)")
@pytest.mark.parametrize("width", [720, 1280])
def test_screenshots(poor, width, tmp_path):
    """At 720 and 1280 px: no word of a header or of a first (name) column split over two
    lines, the first box in the first
    screen, nothing wider than the page; a screenshot is written for a reader to look at."""
    source = tmp_path / "page.html"
    source.write_text(poor[4].replace("</body>", PROBE + "</body>"), encoding="utf-8")
    args = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
            "--disable-background-networking", "--disable-component-update", "--disable-sync",
            "--no-first-run", "--hide-scrollbars", f"--window-size={width},1400",
            "--virtual-time-budget=8000"]
    out = subprocess.run([*args, f"--user-data-dir={tmp_path / 'p1'}", "--dump-dom",
                          source.as_uri()], capture_output=True, text=True, timeout=120).stdout
    shot = tmp_path / f"report_{width}.png"
    subprocess.run([*args, f"--user-data-dir={tmp_path / 'p2'}", f"--screenshot={shot}",
                    (tmp_path / "page.html").as_uri()], capture_output=True, timeout=120)
    for profile in ("p1", "p2"):
        shutil.rmtree(tmp_path / profile, ignore_errors=True)
    found = re.search(r'data-probe="([^"]*)"', out)
    assert found, out[-500:]
    probe = json.loads(found.group(1).replace("&quot;", '"'))
    assert probe["broken"] == [], probe
    assert probe["boxTop"] < 400 and probe["wide"] == 0 and probe["scroll"] <= probe["W"], probe
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@given(st.lists(st.tuples(st.sampled_from(LEVELS), st.sampled_from(
    ["a", "b", "c d", "c  d", "x < y", "ω"])), min_size=1, max_size=12))
def test_findings_box_worst_first_each_once(findings):
    """The box takes the worst level, its headline is the first text of that level, and every
    text (blanks folded) appears once."""
    page = _parse(findings_html(findings))
    worst = max((level for level, _ in findings), key=LEVELS.index)
    assert page.box["class"].split() == ["verdict", worst]
    assert page.box["items"][0] == next(" ".join(t.split()) for lv, t in findings if lv == worst)
    texts = {" ".join(t.split()) for _, t in findings}
    assert sorted(page.box["items"]) == sorted(texts)
