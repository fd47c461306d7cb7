import re

import numpy as np
import pytest

import consistid as ci
from consistid import cli
from consistid.identification.base import random_states
from consistid.cli.config import (config_identify, config_model, config_recordings, identify_keys,
                              load_config)
from consistid.robot.shapes import Ellipsoid
from consistid.errors import ConfigError
from consistid.identification.priors import Neighbourhood

from .conftest import PLANAR_2R, PLANAR_2R_VALUES


@pytest.fixture()
def project(tmp_path, planar_2r):
    """A URDF and two logs (FloBaRoID layout, Unix stamps) under data/, a config under conf/."""
    data = tmp_path / "data"
    data.mkdir()
    (data / "arm.urdf").write_text(PLANAR_2R.format(**PLANAR_2R_VALUES))
    rng = np.random.default_rng(0)
    for k in (1, 2):
        q, dq, ddq = random_states(planar_2r, 300, rng)
        tau = planar_2r.rnea(q, dq, ddq) + 0.2 * np.sign(dq) + 0.01 * rng.standard_normal(q.shape)
        np.savez(data / f"run{k}.npz", times=1.7e9 + 0.005 * np.arange(300), positions=q,
                 velocities=dq, accelerations=ddq, torques=tau)
    (tmp_path / "conf").mkdir()
    return tmp_path


def write(project, text):
    path = project / "conf" / "run.toml"
    path.write_text(text)
    return path


GOOD = """root = ".."
[model]
urdf = "data/arm.urdf"
gravity = [0.0, -9.81, 0.0]
[data]
dir = "data"
joint_names = ["joint1", "joint2"]
trim_start = 0.1
train = ["run1.npz"]
held_out = ["run2.npz"]
[identify]
method = "ols"
friction = ["coulomb"]
"""


def test_paths_resolve_against_root_and_dir_not_the_cwd(project, monkeypatch):
    monkeypatch.chdir(project / "conf")
    cfg = load_config(write(project, GOOD))
    assert cfg.root == project.resolve()
    model = config_model(cfg)
    assert model.joint_names == ["joint1", "joint2"]
    np.testing.assert_allclose(model.gravity, [0.0, -9.81, 0.0])
    train, held = config_recordings(cfg, model)
    t = 1.7e9 + 0.005 * np.arange(300)
    assert train.dataset.n_samples == np.sum(t - t[0] >= 0.1) and held is not None
    assert any("trimmed 0.1 s" in s for s in train.steps)


def test_unknown_and_missing_keys_are_named(project):
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['trim'\] in \[data\]"):
        config_recordings(load_config(write(project, GOOD.replace("trim_start", "trim"))))
    with pytest.raises(ConfigError, match=r"missing table \[model\]"):
        config_model(load_config(write(project, "[data]\ntrain = ['a.npz']\n")))
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(write(project, "[model\n"))


def test_cli_identify_runs_from_a_config(project, capsys):
    assert cli.main(["identify", str(write(project, GOOD))]) == 0
    out = capsys.readouterr().out
    assert "method=ols" in out and "held-out" in out
    held_row = next(line for line in out.splitlines() if line.startswith("held-out"))
    assert float(held_row.split()[3]) < 1.0          # total relative error (%) of a good fit


def test_misspelled_tables_and_identify_keys_are_named(project, capsys):
    with pytest.raises(ConfigError, match=r"unknown table\(s\) or top-level key\(s\) "
                                          r"\['identfy'\]"):
        load_config(write(project, GOOD.replace("[identify]", "[identfy]")))
    # an unknown [identify] key used to reach identify_sdp as a TypeError (traceback)
    path = write(project, GOOD.replace('method = "ols"', 'method = "sdp"\npriorr = "euclidean"'))
    assert cli.main(["identify", str(path)]) == 2
    err = capsys.readouterr().err
    assert "unknown key(s) ['priorr'] in [identify]" in err and "'prior'" in err
    assert {"method", "friction", "prior", "margin", "solver"} <= set(identify_keys())
    assert "dataset" not in identify_keys()


def test_identify_tables_become_objects(project):
    text = GOOD + ('neighbourhood = {mass = 0.2, com = 0.05}\n'
                   'ellipsoids = {link2 = {center = [0.3, 0, 0], semi_axes = [0.4, 0.1, 0.1]}}\n')
    options = config_identify(load_config(write(project, text)))
    assert options["neighbourhood"] == Neighbourhood(mass=0.2, com=0.05)
    ell = options["ellipsoids"]["link2"]
    assert isinstance(ell, Ellipsoid) and ell.contains([0.65, 0.0, 0.0])
    assert not ell.contains([0.3, 0.15, 0.0])
    with pytest.raises(ConfigError, match=r"unknown key\(s\) \['radius'\] in "
                                          r"\[identify.ellipsoids.link2\]"):
        config_identify(load_config(write(project, GOOD + "ellipsoids = {link2 = {radius = 1}}\n")))


def test_cli_payload_checks_its_table(project, capsys):
    base = GOOD.replace("[identify]", "[payload]\nloaded = [\"data/run2.npz\"]\n[identify]")
    assert cli.main(["payload", str(write(project, base.replace(
        "[identify]", 'route = "base_change"\n[identify]')))]) == 2
    # the hint is in the syntax the user writes: TOML (consistid.cli.hints)
    assert 'route = "base_change" is not supported; allowed: "torque", "base-change"' in (
        capsys.readouterr().err)
    assert cli.main(["payload", str(write(project, base.replace(
        'loaded = ["data/run2.npz"]', 'frame = "link2"')))]) == 2
    assert "[payload] needs loaded" in capsys.readouterr().err


def test_cli_recover_has_one_default_for_both_branches(project, tmp_path, capsys):
    """OLS on the logs and a coefficients file of the same (default) columns both work."""
    recover = GOOD.replace("[identify]\nmethod = \"ols\"\nfriction = [\"coulomb\"]\n",
                           '[recover]\nmode = "nearest"\n')
    assert cli.main(["recover", str(write(project, recover))]) == 0
    from_logs = capsys.readouterr().out
    cfg = load_config(write(project, recover))
    model = config_model(cfg)
    res = ci.identify(model, config_recordings(cfg, model)[0].dataset, method="ols")
    np.savez(project / "beta.npz", beta=res.base_parameters, covariance=res.base_covariance)
    path = write(project, recover.replace('mode = "nearest"',
                                          'mode = "nearest"\ncoefficients = "beta.npz"'))
    assert cli.main(["recover", str(path)]) == 0
    from_file = capsys.readouterr().out
    # the same columns: 2 bodies × 10 + 2 joints × (Coulomb, viscous, offset)
    assert from_file.splitlines()[0] == from_logs.splitlines()[0]
    assert "→ 26 standard parameters" in from_file


def test_cli_identify_estimates_the_tilt_when_asked(project, capsys):
    # the logs were simulated level; the planar arm sees its in-plane tilt (about −z) to first
    # order and the out-of-plane one (about x) only through |g|'s in-plane share (second order)
    text = GOOD.replace("gravity = [0.0, -9.81, 0.0]",
                        'gravity = [0.0, -9.81, 0.0]\ntilt = "estimate"')
    assert cli.main(["identify", str(write(project, text))]) == 0
    out = capsys.readouterr().out
    line = next(s for s in out.splitlines() if s.startswith("base tilt"))
    (ax, sx), (az, sz) = (map(float, re.search(rf"([-+.\d]+)° ± ([.\d]+)° about {axis}\b",
                                               line).groups()) for axis in ("x", "-z"))
    assert abs(az) < 3 * sz and sz < 0.1
    assert abs(ax) < 3 * sx and sx > 10 * sz
    with pytest.raises(ConfigError, match=r"for `consistid identify` only"):
        config_model(load_config(write(project, text)))
    with pytest.raises(ConfigError, match=r"tilt = 'yes'"):
        config_model(load_config(write(project, text.replace('"estimate"', '"yes"'))),
                     allow_tilt=True)
    with pytest.raises(ConfigError, match=r"gravity must be three numbers"):
        config_model(load_config(write(project, GOOD.replace("[0.0, -9.81, 0.0]", '"level"'))))
