"""``consistid simulate``: the nominal residual of a MuJoCo arm with two effects."""

import numpy as np
import pytest

from consistid.cli import main
from consistid.errors import OptionError
from consistid.cli.residual_demo import parse_effects, run
from consistid.simulate.effects import Effects


def test_residual_is_explained_by_the_injected_effects():
    demo = run("ur5", ["viscous=0.5", "payload=2.0"], duration=2.0, seed=1)
    rms = lambda x: np.sqrt(np.mean(x ** 2, axis=0))  # noqa: E731
    floor, residual, left = rms(demo.baseline), rms(demo.residual), rms(demo.explained)
    assert np.all(residual > 10 * floor)           # the effects are visible …
    assert np.all(left < 2 * floor + 1e-3)         # … and their closed forms account for them
    assert "shoulder_pan_joint" in str(demo) and "payload" in str(demo)


def test_parse_effects(panda):
    eff = parse_effects(["coulomb=1.5", "payload=1.0"], panda).for_model(panda)
    np.testing.assert_allclose(eff.coulomb, 1.5)
    np.testing.assert_allclose(eff.payload.com, [0, 0, 0.1])   # along panda_joint7's z axis
    with pytest.raises(OptionError, match="NAME=NUMBER"):
        parse_effects(["coulomb"], panda)
    with pytest.raises(OptionError, match="unknown effect 'ripple'"):
        parse_effects(["ripple=1"], panda)


@pytest.mark.filterwarnings("ignore::consistid.errors.TrackingWarning")   # UR3's light wrist
def test_cli_simulate_prints_and_plots(tmp_path, capsys):
    png = tmp_path / "residual.png"
    assert main(["simulate", "--robot", "ur3", "--duration", "1.5", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "no-effect floor" in out and "wrist_3_joint" in out
    assert png.stat().st_size > 10_000
    assert main(["simulate", "--effect", "bogus=1"]) == 2


def test_torque_noise_is_overridden_only_when_given(tmp_path):
    effects = Effects(viscous=0.5, torque_noise=0.2)
    demo = run("ur3", effects, duration=1.5)
    np.testing.assert_allclose(demo.recording.effects.torque_noise, 0.2)     # kept
    noise = demo.recording.tau - demo.recording.true_tau
    assert np.std(noise) == pytest.approx(0.2, rel=0.1)
    demo = run("ur3", effects, duration=1.5, torque_noise=0.01)
    np.testing.assert_allclose(demo.recording.effects.torque_noise, 0.01)    # replaced
    # the plot leaves matplotlib's global state alone: no backend switch, no pyplot figure
    import matplotlib
    before = matplotlib.get_backend()
    matplotlib.use("pdf")
    try:
        assert demo.plot(tmp_path / "r.png").stat().st_size > 10_000
        assert matplotlib.get_backend() == "pdf"
    finally:
        matplotlib.use(before)
