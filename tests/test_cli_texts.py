"""What the ``consistid`` command writes for a user: excitation CSVs named by joints, and
hints in CLI syntax (``--all``), not Python (issue 31)."""

from __future__ import annotations

import numpy as np
import pytest

import consistid as ci
from consistid.cli.hints import cli_text
from consistid.excitation import design_excitation


def test_a_design_csv_is_named_by_joints_and_reloads(planar_2r, tmp_path):
    """``consistid excite`` writes ExcitationDesign.save_csv: columns named by the robot's
    joints, which Dataset.load reads back with the names; a trajectory without names keeps
    q1.."""
    design = design_excitation(planar_2r, harmonics=2, period=4.0, seed=0, n_starts=1,
                               max_iter=3, progress=False)
    path = design.save_csv(tmp_path / "design.csv", 20.0)
    assert path.read_text().startswith("t,q_joint1,q_joint2,dq_joint1,dq_joint2,ddq_joint1")
    back, sampled = ci.Dataset.load(path), design.trajectory.sample(20.0)
    assert back.joint_names == ("joint1", "joint2")
    for f in ("q", "dq", "ddq"):
        np.testing.assert_allclose(getattr(back, f), getattr(sampled, f), rtol=1e-9,
                                   atol=1e-12, err_msg=f)
    with pytest.raises(ci.JointNameError, match="names its joints"):
        ci.Dataset.load(path, joint_names=["a", "b"])
    plain = design.trajectory.save_csv(tmp_path / "plain.csv", 20.0)
    assert plain.read_text().startswith("t,q1,q2,dq1")
    with pytest.raises(ci.ExcitationError, match="1 joint names for 2 joints"):
        design.trajectory.save_csv(tmp_path / "x.csv", 20.0, joint_names=["a"])


def test_summaries_quote_the_cli_option(panda):
    run = ci.simulate.excitation_run(panda, duration=3.0, rate=100.0, seed=2)
    text = ci.identify(panda, run.dataset, method="ols", friction=None).summary(max_rows=5)
    assert "summary(max_rows=None)" in text                   # the library speaks Python
    cli = cli_text(text)
    assert "(--all shows all)" in cli and "max_rows" not in cli
