"""What the ``consistid`` command writes for a user: excitation CSVs named by joints, and
hints in CLI syntax (``--all``), not Python (issue 31)."""

from __future__ import annotations

import warnings

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


def test_identification_summary_lists_each_warning_once_under_the_header(panda):
    """Warnings recorded with a result (``details['warning k']``, as the command line stores
    them) are printed once, under the header, not among the notes (the HTML's first box)."""
    import dataclasses

    run = ci.simulate.excitation_run(panda, duration=3.0, rate=100.0, seed=2)
    res = ci.identify(panda, run.dataset, method="ols", friction=None)
    text = "ExtrapolationWarning: these data go where the training data never went"
    res = dataclasses.replace(res, details={**res.details, "warning 1": text,
                                            "warning 2": text.replace(" data ", "  data ")})
    lines = res.summary(max_rows=5).splitlines()
    at = [k for k, line in enumerate(lines) if "training data never went" in line]
    table_at = next(k for k, line in enumerate(lines) if line.startswith("base parameter"))
    assert len(at) == 1 and at[0] < table_at, lines[:table_at + 1]
    from consistid.identification.report import identification_page

    page = identification_page(res, figures=False).render()     # the HTML's first box too
    box = page.split('<div class="verdict ', 1)[1].split("</div>", 1)[0]
    assert box.count("training data never went") == 1
    assert page.count("training data never went") == 1


def test_cli_identify_shows_each_warning_once_before_the_summary(capsys, tmp_path):
    """``consistid identify`` on the UR5 example: the held-out log goes beyond the trained
    motion (ExtrapolationWarning), scored once and again by the report written after: the
    terminal shows it once, and the summary carries it above the parameter table."""
    from pathlib import Path

    from consistid.cli import main

    config = Path(__file__).parents[1] / "examples" / "ur5" / "identify.toml"
    with warnings.catch_warnings(record=True) as shown:   # what the terminal would show
        warnings.simplefilter("always")
        assert main(["identify", str(config), "-q", "--output", str(tmp_path / "out")]) == 0
    out, _ = capsys.readouterr()
    assert [w.category.__name__ for w in shown].count("ExtrapolationWarning") == 1
    assert out.count("ExtrapolationWarning") == 1
    assert out.index("ExtrapolationWarning") < out.index("base parameter")
    # in the CLI's terms: the trained ranges are in result.json, not a Python attribute
    said = str(next(w.message for w in shown if w.category.__name__ == "ExtrapolationWarning"))
    assert "res.envelope" not in said + out and "result.json's \"envelope\"" in said
