import numpy as np
import pytest

import consistid as ci
from consistid.errors import ModelError
from consistid.robot.model import model_without_dynamics
from consistid.robot.urdf import joint_dynamics, strip_dynamics

from .conftest import PLANAR_2R, PLANAR_2R_VALUES


def with_dynamics(tmp_path, friction2: float):
    text = PLANAR_2R.format(**PLANAR_2R_VALUES)
    text = text.replace('<axis xyz="0 0 1"/><limit', '<axis xyz="0 0 1"/>'
                        '<dynamics damping="0.7" friction="0.3"/><limit', 1)
    text = text.replace('<origin xyz="{l1} 0 0"/>'.format(**PLANAR_2R_VALUES),
                        '<origin xyz="{l1} 0 0"/><dynamics damping="0.2" friction="{f}"/>'
                        .format(f=friction2, **PLANAR_2R_VALUES))
    path = tmp_path / "dyn.urdf"
    path.write_text(text)
    return path


def test_negative_friction_is_refused_by_pinocchio_and_loaded_stripped(tmp_path, planar_2r):
    path = with_dynamics(tmp_path, friction2=-0.4)
    with pytest.raises(ModelError, match="Pinocchio could not read"):
        ci.RobotModel.from_urdf(path)
    model, dyn = model_without_dynamics(path, gravity=(0.0, -9.81, 0.0))
    assert model.source == path and model.name == "dyn"
    assert (dyn["joint1"].damping, dyn["joint1"].friction) == (0.7, 0.3)
    assert (dyn["joint2"].damping, dyn["joint2"].friction) == (0.2, -0.4)
    np.testing.assert_array_equal(model.prior_parameters, planar_2r.prior_parameters)
    stripped = strip_dynamics(path, tmp_path / "clean.urdf")
    assert joint_dynamics(stripped) == {}
    assert "<dynamics" not in stripped.read_text()


def test_bad_dynamics_value_is_named(tmp_path):
    path = tmp_path / "bad.urdf"
    path.write_text('<robot name="r"><link name="a"/><link name="b"/><joint name="j" '
                    'type="revolute"><parent link="a"/><child link="b"/>'
                    '<dynamics damping="x"/></joint></robot>')
    with pytest.raises(ModelError, match=r"joint 'j' has <dynamics damping='x'>"):
        joint_dynamics(path)
