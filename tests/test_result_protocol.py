"""Every result speaks the same words: estimate, std, covariance, conf_int, summary, report,
_repr_html_ (consistid.report.result)."""

from __future__ import annotations

import sys
from html.parser import HTMLParser

import numpy as np
import pytest
from scipy.stats import norm

import consistid as ci
from consistid.report.result import normal_intervals


class _Tags(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)


def _tags(markup: str) -> list[str]:
    parser = _Tags()
    parser.feed(markup)
    return parser.tags


@pytest.fixture(scope="module")
def results(panda):
    run = ci.simulate.excitation_run(panda, duration=6.0, rate=100.0, torque_noise=0.1, seed=3)
    ident = ci.identify(panda, run.dataset, method="ols")
    tilt = ci.estimate_mounting(panda, run.dataset)
    design = ci.design_excitation(panda, harmonics=2, period=4.0, seed=0, n_starts=1,
                                  max_iter=3, progress=False)
    return {"identification": ident, "mounting": tilt, "excitation": design}


@pytest.mark.parametrize("name", ["identification", "mounting"])
def test_std_covariance_and_intervals_agree(results, name):
    res = results[name]
    np.testing.assert_allclose(res.std, np.sqrt(np.diag(res.covariance)))
    ci95 = np.asarray(res.conf_int())            # a labelled frame for an identification
    z = norm.ppf(0.975)
    np.testing.assert_allclose(ci95[:, 0], res.estimate - z * res.std)
    np.testing.assert_allclose(ci95[:, 1], res.estimate + z * res.std)
    half = np.asarray(res.conf_int(0.5))
    assert np.all(half[:, 1] - half[:, 0] < ci95[:, 1] - ci95[:, 0])


def test_identification_intervals_are_labelled_as_statsmodels_does(results, monkeypatch):
    """A DataFrame indexed by base-parameter name (columns lower, upper, the level in attrs);
    labelled=False gives the same numbers as an array, and works without pandas."""
    pd = pytest.importorskip("pandas")
    res = results["identification"]
    frame = res.conf_int(0.1)
    assert isinstance(frame, pd.DataFrame) and list(frame.columns) == ["lower", "upper"]
    assert list(frame.index) == list(res.base.names) and frame.index.name == "parameter"
    assert frame.attrs["alpha"] == 0.1
    z = norm.ppf(0.95)
    name = res.base.names[3]
    assert frame.loc[name, "upper"] == pytest.approx(res.estimate[3] + z * res.std[3])
    np.testing.assert_array_equal(frame.to_numpy(), res.conf_int(0.1, labelled=False))
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ci.MissingDependencyError, match=r"pip install 'consistid\[io\]'"):
        res.conf_int()
    assert res.conf_int(labelled=False).shape == (res.estimate.size, 2)
    with pytest.raises(ci.OptionError, match="alpha"):
        res.conf_int(1.5)


@pytest.mark.parametrize("name", ["identification", "mounting", "excitation"])
def test_report_is_one_html_page_with_real_tables(results, name, tmp_path):
    res = results[name]
    assert isinstance(res.summary(), str) and res.summary()
    path = res.report(tmp_path / f"{name}.html")
    tags = _tags(path.read_text())
    assert "table" in tags and "pre" not in tags
    assert "table" in _tags(res._repr_html_())


def test_payload_speaks_the_same_words(panda, tmp_path):
    from consistid.simulate import MountedPayload

    run = ci.simulate.excitation_run(panda, duration=6.0, rate=100.0, torque_noise=0.05, seed=4)
    joint, carried = MountedPayload(1.5, (0.0, 0.0, 0.05)).parameters(panda)
    theta = panda.prior_parameters.copy()
    theta[10 * joint:10 * joint + 10] += carried
    loaded = ci.simulate.excitation_run(panda, parameters=theta, duration=6.0, rate=100.0,
                                        torque_noise=0.05, seed=5)
    pay = ci.estimate_payload(panda, loaded.dataset, robot=ci.identify(panda, run.dataset))
    assert abs(pay.mass - 1.5) < 5 * pay.mass_std + 0.05
    lo, hi = pay.conf_int()[0]
    assert lo < pay.mass < hi
    assert "table" in _tags(pay.report(tmp_path / "payload.html").read_text())


def test_interval_level_is_checked():
    with pytest.raises(ci.OptionError, match="alpha"):
        normal_intervals(np.zeros(2), np.ones(2), alpha=1.5)
