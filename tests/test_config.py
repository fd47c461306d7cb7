import numpy as np
import pytest

from consistid import cli
from consistid.base import random_states
from consistid.config import config_model, config_recordings, load_config
from consistid.errors import ConfigError

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
