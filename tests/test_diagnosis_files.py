"""``Diagnosis.save`` / ``Diagnosis.load``: one JSON file that reloads to a diagnosis with the
same effects, verdict, tables, report and corrected model (issue 31)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import consistid as ci
from consistid.data.dataset import Dataset
from consistid.diagnosis.report import diagnosis_page
from consistid.errors import ResultFileError
from consistid.excitation import FourierTrajectory
from consistid.simulate import record
from consistid.simulate.effects import Effects


@pytest.fixture(scope="module")
def diagnosed(panda):
    """A MuJoCo Panda with Coulomb friction on one joint: train 6 s, held out 4 s, 100 Hz."""
    effects = Effects(torque_noise=0.05).with_effect("coulomb", 1.5, joints=[2])
    data = []
    for seed, duration in ((21, 6.0), (22, 4.0)):
        traj = FourierTrajectory.random(panda, 4, 6.0, seed)
        rec = record(panda, traj, effects, duration=duration, rate=100.0, seed=seed)
        data.append(Dataset.from_recording(rec.t, rec.q, rec.tau))
    diag = ci.diagnose(panda, data[0], held_out=data[1], effects=["coulomb", "viscous",
                                                                  "offset"], progress=False)
    return diag, data[1]


def test_a_diagnosis_round_trips(diagnosed, tmp_path):
    diag, held = diagnosed
    path = diag.save(tmp_path / "diagnosis.json")
    json.loads(path.read_text())                              # plain JSON
    back = ci.Diagnosis.load(path)
    assert back.summary() == diag.summary() and back.verdict == diag.verdict
    assert [e.name for e in back.effects] == [e.name for e in diag.effects] != []
    for f in ("noise_floor", "rms_nominal", "rms_final", "library_floor"):
        np.testing.assert_array_equal(getattr(back, f), getattr(diag, f), err_msg=f)
    np.testing.assert_array_equal(back.where.psd, diag.where.psd)
    # the corrected model predicts the same torques, bit for bit, on data it never saw
    np.testing.assert_array_equal(back.fit.predict(held), diag.fit.predict(held))
    assert back.fit.model.joint_names == diag.fit.model.joint_names
    assert back.report(tmp_path / "r.txt").read_text() == \
        diag.report(tmp_path / "d.txt").read_text()
    assert dataclasses.fields(back) == dataclasses.fields(diag)


def test_a_file_that_is_not_a_diagnosis_is_named(tmp_path):
    bad = tmp_path / "x.json"
    bad.write_text('{"format": "consistid.identification-result"}')
    with pytest.raises(ResultFileError, match="not a consistid diagnosis file"):
        ci.Diagnosis.load(bad)
    bad.write_text('{"format": "consistid.diagnosis", "version": 1, "diagnosis": '
                   '{"__dataclass__": "os:system"}}')
    with pytest.raises(ResultFileError, match="not a consistid.diagnosis class"):
        ci.Diagnosis.load(bad)


def test_text_summary_lists_each_warning_once_under_the_header(diagnosed):
    """The command line appends the warnings it caught as ``warning: …`` notes; the text
    summary, as the HTML's first box, shows each once near the top (not among the notes at
    the bottom), and a note repeated is printed once."""
    diag, _ = diagnosed
    warned = "DataQualityWarning: train.csv: a torque channel reads 0"
    said = "the noise floor cannot be seen on joint 3"        # noted, then warned in full
    noted = dataclasses.replace(diag, notes=(*diag.notes, "a note", "a  note", said,
                                             f"warning: {warned}", f"warning:  {warned}",
                                             f"warning: UserWarning: diagnose: {said}; so"))
    lines = noted.summary().splitlines()
    at = [k for k, line in enumerate(lines) if warned in line]
    assert len(at) == 1 and at[0] < 8, lines[:10]
    assert sum("a note" in line for line in lines) == 1
    assert sum(said in line for line in lines) == 1               # in the warning only
    assert "Warnings (2, each once):" in lines
    page = diagnosis_page(noted, figures=False).render()
    box = page.split('<div class="verdict ', 1)[1].split("</div>", 1)[0]
    assert box.count(warned) == 1 and page.count(warned) == 1
    assert page.count(said) == 1
    assert box.startswith("warn") or box.startswith("bad")     # a warning is no "ok" box
