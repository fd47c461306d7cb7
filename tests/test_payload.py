"""Payload estimation: both routes on a hidden payload, identifiability, constraints, frames."""

import re
import warnings

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.cli import main
from consistid.robot.shapes import Ellipsoid
from consistid.errors import OptionError, PoorExcitationWarning
from consistid.robot.inertia import from_mass_com_inertia, perturb, pseudo_inertia
from consistid.estimation.payload import estimate_payload, frame_transform, payload_from_base_change

from .conftest import random_states

MASS = 1.5
COM = np.array([0.03, 0.0, 0.04])          # 5 cm from the flange origin
NOISE = 0.5


def _box(mass, com, dims):
    a, b, c = dims
    return from_mass_com_inertia(mass, com, mass / 12 * np.diag([b * b + c * c, a * a + c * c,
                                                                   a * a + b * b]))


@pytest.fixture(scope="module")
def hidden(panda):
    """Robot truth (URDF ±20 %), a 1.5 kg box on the flange, unloaded/loaded/held-out runs."""
    truth = perturb(panda.prior_parameters, 0.2, np.random.default_rng(11))
    flange = panda.pin_model.frames[panda.pin_model.getFrameId("panda_link8")].placement
    payload = _box(MASS, COM, (0.10, 0.08, 0.06))
    loaded = truth.copy()
    loaded[60:70] += frame_transform(flange.rotation, flange.translation) @ payload
    runs = [ci.simulate.excitation_run(panda, p, duration=d, rate=200.0, torque_noise=NOISE,
                                       seed=s).dataset
            for p, d, s in ((truth, 10.0, 21), (loaded, 10.0, 22), (loaded, 5.0, 23))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PoorExcitationWarning)
        unloaded_res = ci.identify(panda, runs[0], method="ols", friction=None)
        loaded_res = ci.identify(panda, runs[1], method="ols", friction=None)
    return dict(payload=payload, unloaded=unloaded_res, unloaded_data=runs[0],
                loaded_data=runs[1], loaded_res=loaded_res, held=runs[2])


@pytest.mark.parametrize("route", ["torque", "base-change"])
def test_hidden_payload_both_routes(panda, hidden, route):
    loaded = hidden["loaded_data"] if route == "torque" else hidden["loaded_res"]
    pay = estimate_payload(panda, loaded, robot=hidden["unloaded"], frame="panda_link8")
    assert pay.method == route and pay.frame == "panda_link8" and pay.body == "panda_link7"
    assert abs(pay.mass - MASS) / MASS < 0.03          # fails for a 10 % mass error
    assert np.linalg.norm(pay.com - COM) < 0.005
    assert pay.rank == 10 and all(pay.identifiable) and pay.min_eigenvalue >= -1e-9
    # the reported uncertainty is honest: the truth lies within 4 σ
    assert np.all(np.abs(pay.parameters - hidden["payload"]) < 4 * pay.std + 1e-9)
    assert 0 < pay.mass_std < 0.03 * MASS
    assert "payload.Izz" in str(pay)


def test_held_out_torques_reject_a_ten_percent_mass_error(panda, hidden):
    """Power check: on held-out loaded data the estimate leaves only the noise, a payload 10 %
    heavier (same CoM and shape) leaves clearly more."""
    pay = estimate_payload(panda, hidden["loaded_data"], robot=hidden["unloaded"],
                           frame="panda_link8")
    held = hidden["held"]
    flange = panda.pin_model.frames[panda.pin_model.getFrameId("panda_link8")].placement
    y = ci.regressor(panda, held.q, held.dq, held.ddq)[:, 60:70] @ frame_transform(
        flange.rotation, flange.translation)
    rest = held.tau.ravel() - hidden["unloaded"].predict(held).ravel()

    def rms(theta):
        return np.sqrt(np.mean((rest - y @ theta) ** 2)) / NOISE

    assert rms(pay.parameters) < 1.03
    assert rms(1.1 * pay.parameters) > 1.1


def test_planar_arm_identifiability_closed_form(planar_2r):
    """Planar 2R about z: the payload on link 2 acts through m (via l1), m·cx, m·cy and Izz only,
    in both routes, whatever the data."""
    expected = (True, True, True, False, False, False, False, False, False, True)
    payload = _box(0.5, [0.1, 0.02, 0.0], (0.05, 0.05, 0.05))
    truth = planar_2r.prior_parameters
    loaded = truth.copy()
    loaded[10:] += payload
    runs = [ci.simulate.excitation_run(planar_2r, p, duration=5.0, rate=200.0, torque_noise=0.01,
                                       seed=s).dataset for p, s in ((truth, 1), (loaded, 2))]
    un = ci.identify(planar_2r, runs[0], method="ols", friction=None)
    lo = ci.identify(planar_2r, runs[1], method="ols", friction=None)
    for loaded_info in (runs[1], lo):
        pay = estimate_payload(planar_2r, loaded_info, robot=un)
        assert pay.identifiable == expected and pay.rank == 4
        assert len(pay.unidentified) == 6 and np.all(np.isinf(pay.std[~np.array(expected)]))
        assert pay.mass == pytest.approx(0.5, rel=0.03)
        assert pay.parameters[1:3] == pytest.approx(payload[1:3], abs=2e-3)
        assert any("whatever the data" in n for n in pay.notes)


def test_static_data_warn_and_report_minimum_states(panda):
    q, _, _ = random_states(panda, 6, seed=3)
    zero = np.zeros_like(q)
    payload = _box(1.2, [0.0, 0.02, 0.05], (0.1, 0.1, 0.1))
    theta = panda.prior_parameters.copy()
    theta[60:70] += payload
    tau = (ci.regressor(panda, q, zero, zero) @ theta).reshape(q.shape)
    data = ci.Dataset(t=np.arange(6.0), q=q, dq=zero, ddq=zero, tau=tau)
    with pytest.warns(PoorExcitationWarning, match="rank 4"):
        pay = estimate_payload(panda, data, robot=panda.prior_parameters, friction=None)
    assert pay.rank == 4 and pay.identifiable == (True,) * 4 + (False,) * 6
    assert pay.mass == pytest.approx(1.2, rel=1e-6)
    assert pay.com == pytest.approx([0.0, 0.02, 0.05], abs=1e-6)
    assert any("generic (q, q̇, q̈) states" in n for n in pay.notes)


def test_ellipsoid_bounds_the_payload(panda, hidden):
    """A 2 cm ball around the flange origin cannot hold a CoM 5 cm away: the estimate must
    respect it (density inside the ellipsoid: tr(J Q) ≥ 0)."""
    ball = Ellipsoid.from_semi_axes([0.0, 0.0, 0.0], [0.02, 0.02, 0.02])
    pay = estimate_payload(panda, hidden["loaded_data"], robot=hidden["unloaded"],
                           frame="panda_link8", ellipsoid=ball)
    assert ball.contains(pay.com)
    assert np.trace(pseudo_inertia(pay.parameters) @ ball.q_matrix()) >= -1e-8


def test_bad_inputs(panda, hidden):
    with pytest.raises(OptionError, match="unloaded IdentificationResult"):
        estimate_payload(panda, hidden["loaded_res"], robot=panda.prior_parameters)
    with pytest.raises(ci.ModelError, match="unknown frame"):
        estimate_payload(panda, hidden["loaded_data"], robot=hidden["unloaded"], frame="nope")
    with pytest.raises(OptionError, match="solver='NOPE'"):   # as identify and recover do
        estimate_payload(panda, hidden["loaded_data"], robot=hidden["unloaded"], solver="NOPE")
    # options that would be ignored are refused: columns other than the result's, base= with
    # two results (whose own maps are used)
    for loaded in (hidden["loaded_data"], hidden["loaded_res"]):
        with pytest.raises(OptionError, match="other per-joint columns"):
            estimate_payload(panda, loaded, robot=hidden["unloaded"], friction=("coulomb",))
    with pytest.raises(OptionError, match="base= is for coefficient vectors"):
        payload_from_base_change(panda, hidden["unloaded"], hidden["loaded_res"],
                                 base=hidden["unloaded"].base)
    # a bare robot vector is read with identify's default columns; a 70-vector names its setting
    with pytest.raises(ci.ModelError, match=r"needs \(91,\).*friction=None, armature=False"):
        estimate_payload(panda, hidden["loaded_data"], robot=panda.prior_parameters)


def test_wrongly_typed_options_are_named(panda, hidden):
    for options, message in ((dict(mass_range=5), "mass_range must be a pair"),
                             (dict(mass_range=("a", None)), "mass_range bound must be a finite"),
                             (dict(com_bounds=1), "com_bounds must be \\(lower, upper\\)"),
                             (dict(com_bounds=([0, 0, 1], [0, 0, 0])), "lower ≤ upper"),
                             (dict(ellipsoid=3), "ellipsoid must be a consistid.Ellipsoid"),
                             (dict(frame=5), "frame must be a frame/body name")):
        with pytest.raises(OptionError, match=message):
            estimate_payload(panda, hidden["loaded_data"], robot=hidden["unloaded"], **options)
        with pytest.raises(OptionError, match=message):
            payload_from_base_change(panda, hidden["unloaded"], hidden["loaded_res"], **options)
    # a bounds array is a pair like a tuple
    estimate_payload(panda, hidden["loaded_data"], robot=hidden["unloaded"],
                     mass_range=np.array([0.5, 3.0]))
    # a robot identified under another gravity (a tilted mounting) is refused with the level model
    with pytest.raises(ci.ModelError, match="identified with gravity"):
        estimate_payload(panda.with_gravity([0.1, 0.0, -9.81]), hidden["loaded_data"],
                         robot=hidden["unloaded"])


def test_one_covariance_only_is_noted(panda, hidden):
    """Loaded coefficients as a bare vector: they have no covariance, so only the unloaded
    result's weights the fit, and the payload says the loaded set was treated as exact."""
    pay = payload_from_base_change(panda, hidden["unloaded"],
                                   hidden["loaded_res"].base_parameters, frame="panda_link8")
    assert any("only the unloaded coefficients have a covariance: the loaded ones are treated "
               "as exact" in n for n in pay.notes)
    assert abs(pay.mass - MASS) / MASS < 0.05


def test_cli_payload(panda, hidden, tmp_path, capsys):
    """The CLI identifies the unloaded robot on the unloaded run and finds the hidden 1.5 kg."""
    hidden["loaded_data"].save(tmp_path / "loaded.npz")
    hidden["unloaded_data"].save(tmp_path / "unloaded.npz")
    (tmp_path / "payload.toml").write_text(
        f'[model]\nurdf = "{panda.source}"\n'
        'locked_joints = ["panda_finger_joint1", "panda_finger_joint2"]\n'
        '[data]\ntrain = ["unloaded.npz"]\n[identify]\nfriction = []\n'
        '[payload]\nloaded = ["loaded.npz"]\nframe = "panda_link8"\nroute = "torque"\n')
    assert main(["payload", str(tmp_path / "payload.toml")]) == 0
    out = capsys.readouterr().out
    assert "payload on 'panda_link7' in frame 'panda_link8'" in out
    mass = float(re.search(r"^mass\s+(\S+) ±", out, re.M).group(1))
    com = np.array(re.search(r"^CoM\s+\[([^\]]*)\]", out, re.M).group(1).split(), dtype=float)
    assert abs(mass - MASS) / MASS < 0.03
    assert np.linalg.norm(com - COM) < 0.005


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2 ** 31 - 1))
def test_frame_transform_matches_pinocchio_and_composes(seed):
    np.random.seed(seed % (2 ** 32))      # pinocchio's Random draws from numpy's global state
    x1, x2, inertia = pin.SE3.Random(), pin.SE3.Random(), pin.Inertia.Random()
    a1 = frame_transform(x1.rotation, x1.translation)
    a2 = frame_transform(x2.rotation, x2.translation)
    pi = inertia.toDynamicParameters()
    assert np.allclose(a1 @ pi, x1.act(inertia).toDynamicParameters(), atol=1e-12)
    x12 = x1 * x2
    assert np.allclose(a1 @ a2, frame_transform(x12.rotation, x12.translation), atol=1e-12)
