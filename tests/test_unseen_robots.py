"""Robots nobody tuned to, built from URDF text: the text itself given to ``from_urdf``, a
massless link, malformed trees (a loop, two roots, a revolute joint without ``<limit>`` …), and
continuous / prismatic / fixed-in-the-middle joints identified against their own RNEA, and a
body whose URDF inertia no physical body has (each group but the joint kinds failed before its
fix)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import consistid as ci
from consistid.errors import ModelError, ModelWarning

from .conftest import PLANAR_2R, PLANAR_2R_VALUES, random_states


def link(name, m=1.0, c=(0.1, 0.0, 0.0), inertia=(0.01, 0.01, 0.01)):
    if m is None:
        return f'<link name="{name}"/>'
    return (f'<link name="{name}"><inertial><origin xyz="{c[0]} {c[1]} {c[2]}"/>'
            f'<mass value="{m}"/><inertia ixx="{inertia[0]}" ixy="0" ixz="0" '
            f'iyy="{inertia[1]}" iyz="0" izz="{inertia[2]}"/></inertial></link>')


def joint(name, parent, child, kind="revolute", axis="0 0 1", xyz="0 0 0", limit=True):
    lim = ('<limit lower="-3" upper="3" velocity="5" effort="100"/>'
           if limit and kind in ("revolute", "prismatic") else "")
    ax = f'<axis xyz="{axis}"/>' if kind != "fixed" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><origin xyz="{xyz}"/>{ax}{lim}</joint>')


def robot(*elements, name="arm"):
    return f'<?xml version="1.0"?><robot name="{name}">' + "".join(elements) + "</robot>"


TWO_R = [link("base", None), link("l1", 2.0, (0.4, 0, 0), (0.01, 0.045, 0.05)),
         link("l2", 1.5, (0.3, 0, 0), (0.01, 0.03, 0.035)),
         joint("j1", "base", "l1"), joint("j2", "l1", "l2", xyz="0.8 0 0")]


# ------------------------------------------------------------------ URDF text
def test_urdf_text_builds_the_same_model_as_the_file(tmp_path):
    text = PLANAR_2R.format(**PLANAR_2R_VALUES)
    (tmp_path / "arm.urdf").write_text(text)
    from_file = ci.RobotModel.from_urdf(tmp_path / "arm.urdf")
    from_text = ci.RobotModel.from_urdf(text)
    assert from_text.name == "planar2r"                      # the <robot name>
    assert from_text.joint_names == from_file.joint_names
    assert np.array_equal(from_text.prior_parameters, from_file.prior_parameters)
    q, dq, ddq = random_states(from_file, 20, 0)
    assert np.allclose(from_text.rnea(q, dq, ddq), from_file.rnea(q, dq, ddq), atol=1e-12)
    # the text stays readable for the writers that re-read the source
    out = tmp_path / "out.urdf"
    from_text.to_urdf(out)
    again = ci.RobotModel.from_urdf(out)
    assert np.allclose(again.prior_parameters, from_file.prior_parameters)


def test_bad_urdf_text_is_named_not_called_a_missing_file():
    with pytest.raises(ModelError, match="no <limit>") as err:
        ci.RobotModel.from_urdf(robot(link("base", None), link("l1"),
                                      joint("j1", "base", "l1", limit=False)))
    assert "does not exist" not in str(err.value)


# ------------------------------------------------------------------ massless links
@pytest.mark.parametrize("massless", [link("l1", None), link("l1", 0.0, (0, 0, 0), (0, 0, 0)),
                                      link("l1", 0.0, (0, 0, 0), (0.01, 0.02, 0.03))])
def test_a_massless_link_survives_its_own_parameters(massless):
    model = ci.RobotModel.from_urdf(robot(TWO_R[0], massless, *TWO_R[2:]))
    again = model.with_parameters(model.prior_parameters)       # was: "mx = nan"
    assert np.array_equal(again.prior_parameters, model.prior_parameters)
    q, dq, ddq = random_states(model, 20, 1)
    assert np.allclose(again.rnea(q, dq, ddq), model.rnea(q, dq, ddq), atol=1e-12)


# ------------------------------------------------------------------ malformed trees
MALFORMED = {
    "loop": (robot(*TWO_R, joint("j3", "l2", "l1")),
             r"link 'l1' is the child of joints 'j1' and 'j3'"),
    "two roots": (robot(*TWO_R, link("spare")), r"2 root links \['base', 'spare'\]"),
    "duplicate joint": (robot(*TWO_R, link("l3"), joint("j2", "l2", "l3")),
                        r"joint name\(s\) \['j2'\] defined more than once"),
    "missing link": (robot(*TWO_R[:2], joint("j1", "base", "l1"), joint("j2", "l1", "nope")),
                     r"joint 'j2' has <child link='nope'>, which is not a <link>"),
    "no limit": (robot(*TWO_R[:3], joint("j1", "base", "l1"),
                       joint("j2", "l1", "l2", kind="prismatic", limit=False)),
                 r"prismatic joint 'j2' has no <limit>"),
    "not a robot": ('<sdf version="1.6"><model name="m"/></sdf>', r"root element is <sdf>"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_a_malformed_tree_is_named(case):
    text, message = MALFORMED[case]
    with pytest.raises(ModelError, match=message):
        ci.RobotModel.from_urdf(text)


# ------------------------------------------------------------------ joint kinds
KINDS = {
    "continuous": robot(*TWO_R[:4], joint("j2", "l1", "l2", kind="continuous", axis="0 1 0",
                                          xyz="0.8 0 0")),
    "prismatic": robot(*TWO_R[:4], joint("j2", "l1", "l2", kind="prismatic", axis="1 0 0",
                                         xyz="0.8 0 0")),
    "fixed in the middle": robot(link("base", None), link("l1", 2.0, (0.4, 0, 0)),
                                 link("mid", 0.5, (0, 0, 0.05)), link("l2", 1.5, (0.3, 0, 0)),
                                 joint("j1", "base", "l1", axis="0 1 0"),
                                 joint("jf", "l1", "mid", kind="fixed", xyz="0.4 0 0"),
                                 joint("j2", "mid", "l2", axis="0 1 0", xyz="0.4 0 0")),
}


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_ols_reproduces_rnea_on_other_joint_kinds(kind):
    model = ci.RobotModel.from_urdf(KINDS[kind])
    assert model.nv == 2
    q, dq, ddq = random_states(model, 400, 2)
    tau = model.rnea(q, dq, ddq)
    data = ci.Dataset(t=0.005 * np.arange(400), q=q, dq=dq, ddq=ddq, tau=tau)
    res = ci.identify(model, data, method="ols", friction=None)
    assert np.max(res.rms(data)) < 1e-8 * np.max(np.abs(tau))


# ------------------------------------------------------------------ non-physical inertia
@pytest.mark.parametrize("inertia, reason", [((0.01, 0.01, 0.1), "triangle inequality"),
                                             ((-0.01, 0.01, 0.01), "not positive definite")])
def test_a_non_physical_urdf_inertia_warns_on_load(inertia, reason):
    text = robot(TWO_R[0], link("l1", 2.0, (0.4, 0, 0), inertia), *TWO_R[2:])
    with pytest.warns(ModelWarning, match=rf"1 of 2 bodies .*l1: .*{reason}"):
        ci.RobotModel.from_urdf(text)


def test_the_load_warning_says_what_identify_does_with_a_non_physical_body():
    """The warning on load said the default log-det prior refuses such a body; since
    prior='auto' falls back to the Euclidean prior, only an explicit prior='logdet' does."""
    text = robot(TWO_R[0], link("l1", 2.0, (0.4, 0, 0), (0.01, 0.01, 0.1)), *TWO_R[2:])
    with pytest.warns(ModelWarning, match=r"Euclidean.*prior='logdet' refuses them") as load:
        model = ci.RobotModel.from_urdf(text)
    assert "default log-det prior refuses" not in str(load[0].message)
    q, dq, ddq = random_states(model, 400, 2)
    data = ci.Dataset(t=0.005 * np.arange(400), q=q, dq=dq, ddq=ddq, tau=model.rnea(q, dq, ddq))
    with pytest.raises(ci.errors.InconsistentParametersError, match="l1"):
        ci.identify(model, data, friction=None, prior="logdet")
    with pytest.warns(ModelWarning, match=r"l1.*prior='euclidean' instead"):
        assert ci.identify(model, data, friction=None).is_consistent


@pytest.mark.parametrize("text", [robot(*TWO_R), robot(TWO_R[0], link("l1", None), *TWO_R[2:]),
                                  PLANAR_2R.format(**PLANAR_2R_VALUES)])
def test_physical_and_massless_bodies_load_without_a_model_warning(text):
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelWarning)
        ci.RobotModel.from_urdf(text)


# ------------------------------------------------------------------ the model's own API
def test_configuration_takes_a_batch_of_samples_for_continuous_joints():
    kinova = ci.RobotModel.example("kinova")                 # continuous joints: nq = 9, nv = 6
    q = np.random.default_rng(0).uniform(-3, 3, (4, 6))
    batch = kinova.configuration(q)                          # was: ValueError from numpy
    assert batch.shape == (4, 9)
    assert np.array_equal(batch, np.array([kinova.configuration(qk) for qk in q]))
    with pytest.raises(ci.errors.JointCountError, match=r"not \(6,\) or \(N, 6\)"):
        kinova.configuration(np.zeros(5))


@pytest.mark.parametrize("bad, message", [(None, "needs the URDF's path or its XML text"),
                                          ("", "needs the URDF's path or its XML text")])
def test_from_urdf_without_a_path_is_named(bad, message):
    with pytest.raises(ModelError, match=message):           # None was a raw TypeError
        ci.RobotModel.from_urdf(bad)


def test_from_urdf_of_a_folder_or_bytes(tmp_path):
    (tmp_path / "arm.urdf").write_text(robot(*TWO_R))
    with pytest.raises(ModelError, match=r"is a folder, not a file; it holds \['arm.urdf'\]"):
        ci.RobotModel.from_urdf(tmp_path)
    from_bytes = ci.RobotModel.from_urdf((tmp_path / "arm.urdf").read_bytes())
    assert from_bytes.joint_names == ["j1", "j2"]


def test_to_urdf_never_writes_over_its_source(tmp_path):
    source = tmp_path / "arm.urdf"
    source.write_text(robot(*TWO_R))
    model = ci.RobotModel.from_urdf(source)
    with pytest.raises(ModelError, match="would write over the URDF"):
        model.to_urdf(source)                                 # was: overwritten silently
    assert source.read_text() == robot(*TWO_R)
    model.to_urdf(tmp_path / "copy.urdf")


def test_gravity_in_mm_and_a_lock_in_degrees_warn():
    model = ci.RobotModel.from_urdf(robot(*TWO_R))
    with pytest.warns(ModelWarning, match=r"magnitude 9810 m/s².*mm/s²"):
        model.with_gravity((0.0, 0.0, -9810.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", ModelWarning)
        model.with_gravity((0.0, 0.0, -9.81))
        model.with_gravity((0.0, 0.0, 0.0))                   # zero-g: legitimate
    with pytest.warns(ModelWarning, match=r"'j2' at 90 outside \[-3, 3\].*degrees"):
        ci.RobotModel.from_urdf(robot(*TWO_R), locked_joints=["j2"],
                                locked_configuration={"j2": 90.0})


def test_diagnosis_against_a_massless_nominal_link_uses_no_prior():
    """A URDF whose l1 is massless (a placeholder) against a robot whose l1 has 2 kg: the
    consistent refit of the inertia cannot take a log-det prior around a body that cannot exist,
    and a Euclidean pull towards it kept l1 near zero mass (j1 left 365 × the floor); it fits
    without a prior, says so, and explains most of j1's gap."""
    from consistid.simulate import Effects, record

    joints = [joint("j1", "base", "l1", axis="0 1 0"),                # in the gravity plane
              joint("j2", "l1", "l2", axis="0 1 0", xyz="0.8 0 0")]
    truth = ci.RobotModel.from_urdf(robot(*TWO_R[:3], *joints))
    nominal = ci.RobotModel.from_urdf(robot(TWO_R[0], link("l1", 0.0, (0, 0, 0), (0, 0, 0)),
                                            TWO_R[2], *joints))
    traj = ci.FourierTrajectory.random(truth, harmonics=4, period=8.0, seed=3)
    rec = record(truth, traj, Effects(torque_noise=0.01), duration=16.0, rate=500.0, seed=0)
    data = ci.Dataset.from_recording(rec.t, rec.q, rec.tau)
    diag = ci.diagnose(nominal, data)
    assert diag.effects[0].name == "inertia"
    assert any("without a prior" in n and "l1" in n for n in diag.notes), diag.notes
    assert diag.rms_final[0] < 0.05 * diag.rms_nominal[0], (diag.rms_final, diag.rms_nominal)
