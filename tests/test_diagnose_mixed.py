"""Inertia and friction together (issue 27): the rigid-body candidates scored near the nominal
bodies with every joint's friction free beside them.

Truth: the prior's weight from data drawn with a known prior precision; the base-parameter
precision against the constrained minimum of the standard prior (its definition, solved by its
KKT system); end to end (slow), a MuJoCo simulation of the xArm7 with every body's inertia off
and friction on every joint, judged against ``identify(method="sdp")`` on the same logs."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import consistid as ci
from consistid.diagnosis.candidates import EffectLibrary
from consistid.diagnosis.interaction import companions, residual_scale
from consistid.diagnosis.remainder import REMAINDER_RATIO
from consistid.diagnosis.rigid_prior import evidence_prior_weight, prior_curvature
from consistid.identification.priors import logdet_metric
from consistid.identification.sdp import EVIDENCE_RANGE, default_prior_weight


@pytest.mark.parametrize("gamma_true", [0.5, 2.0, 8.0])
def test_evidence_weight_recovers_the_prior_precision_the_parameters_were_drawn_with(
        gamma_true):
    """θ ~ N(0, (γ S)⁻¹), z = Aθ + e with e ~ N(0, 1): the weight of greatest evidence is γ
    within sampling error (200 well-determined parameters)."""
    rng = np.random.default_rng(int(10 * gamma_true))
    k, m = 200, 2000
    q, _ = np.linalg.qr(rng.normal(size=(k, k)))
    s = q @ np.diag(rng.uniform(0.5, 2.0, k)) @ q.T
    theta = np.linalg.cholesky(np.linalg.inv(gamma_true * s)) @ rng.normal(size=k)
    a = rng.normal(size=(m, k)) * rng.uniform(0.2, 1.0, k)     # unequal column scales
    z = a @ theta + rng.normal(size=m)
    gamma = evidence_prior_weight(a.T @ a, a.T @ z, s)
    lo, hi = EVIDENCE_RANGE
    assert lo * default_prior_weight() <= gamma <= hi * default_prior_weight()
    assert gamma == pytest.approx(gamma_true, rel=0.3)


def test_inertia_precision_is_the_standard_prior_marginalised_onto_base_parameters():
    """``δβᵀ P δβ = min {δπᵀ S δπ : B δπ = δβ}`` (the Gaussian prior on the standard
    parameters seen on the base ones), the minimum solved here by its KKT system."""
    model = ci.RobotModel.example("ur5")
    library = EffectLibrary(model, ("inertia", "payload", "coulomb"))
    atoms = library.atoms()
    nominal = model.prior_parameters
    curvature = prior_curvature(library, atoms, nominal)
    sizes = np.cumsum([0] + [a.n_parameters for a in atoms])
    i = [a.effect for a in atoms].index("inertia")
    p_beta = curvature[sizes[i]:sizes[i + 1], sizes[i]:sizes[i + 1]]
    metrics = [logdet_metric(nominal[10 * b:10 * b + 10]) for b in range(model.n_bodies)]
    s = np.zeros((10 * model.n_bodies,) * 2)
    for b, w in enumerate(metrics):
        s[10 * b:10 * b + 10, 10 * b:10 * b + 10] = w.T @ w
    b_mat = library.base.matrix
    rng = np.random.default_rng(3)
    for _ in range(3):
        beta = rng.normal(size=b_mat.shape[0]) * 1e-2
        n, r = s.shape[0], b_mat.shape[0]
        kkt = np.block([[2 * s, b_mat.T], [b_mat, np.zeros((r, r))]])
        pi = np.linalg.solve(kkt, np.concatenate([np.zeros(n), beta]))[:n]
        assert beta @ p_beta @ beta == pytest.approx(pi @ s @ pi, rel=1e-6)
    # payload: the last body's metric; friction columns carry no prior
    j = [a.effect for a in atoms].index("payload")
    np.testing.assert_allclose(curvature[sizes[j]:sizes[j + 1], sizes[j]:sizes[j + 1]],
                               metrics[-1].T @ metrics[-1])
    coulomb = [k for k, a in enumerate(atoms) if a.effect == "coulomb"]
    assert not curvature[sizes[coulomb[0]]:sizes[coulomb[-1] + 1]].any()
    # an unrealisable nominal body: no prior (the final fit has none either)
    flat = nominal.copy()
    flat[10:20] = 0.0
    assert prior_curvature(library, atoms, flat) is None


@settings(max_examples=30, deadline=None)
@given(st.lists(st.integers(0, 11), unique=True, max_size=12))
def test_companions_are_the_friction_atoms_not_yet_chosen(chosen):
    """inertia's and payload's companions: every Coulomb and viscous atom not chosen; an
    effect without companions has none."""
    model = ci.RobotModel.example("ur5")
    atoms = EffectLibrary(model, ("coulomb", "viscous", "inertia", "payload", "gain")).atoms()
    friction = {k for k, a in enumerate(atoms) if a.effect in ("coulomb", "viscous")}
    for k, a in enumerate(atoms):
        got = companions(atoms, chosen, k)
        if a.effect in ("inertia", "payload"):
            assert set(got) == friction - set(chosen)
        else:
            assert got == []


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 10 ** 6), st.integers(2, 9))
def test_residual_weights_fit_the_same_whatever_the_floors(seed, nv):
    """The arm-wide atom's weights ``w_j · residual_scale`` are ``N / SSE_j`` of the raw residual,
    whatever floors ``σ_j`` it was expressed against (a floor read too high or too low changes
    nothing), so the joint-weighted least-squares fit they give is the same: checked against
    the fit of the rows each divided by its joint's residual RMS."""
    rng = np.random.default_rng(seed)
    n, p = 200, 3
    phi = rng.normal(size=(n, nv, p))
    r = rng.normal(size=(n, nv)) * rng.uniform(0.01, 10.0, nv)      # per-joint variances
    sse = np.sum(r ** 2, axis=0)
    fits = []
    for _ in range(2):
        w = 1.0 / rng.uniform(0.01, 10.0, nv) ** 2                   # any floors
        wj = w * residual_scale(w * sse, n)
        np.testing.assert_allclose(wj, n / sse, rtol=1e-12)
        g = np.einsum("j,njp,njq->pq", wj, phi, phi)
        fits.append(np.linalg.solve(g, np.einsum("j,njp,nj->p", wj, phi, r)))
    rms = np.sqrt(sse / n)
    direct = np.linalg.lstsq((phi / rms[None, :, None]).reshape(-1, p),
                             (r / rms).reshape(-1), rcond=None)[0]
    np.testing.assert_allclose(fits[0], direct, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(fits[1], direct, rtol=1e-8, atol=1e-12)


def _train_and_held(model: ci.RobotModel, params: np.ndarray, eff, rng: np.random.Generator,
                    seed: int) -> tuple[ci.Dataset, ci.Dataset]:
    """30 s of training and 10 s of held-out excitation at 500 Hz, simulated in MuJoCo (1 kHz
    physics) with the standard parameters ``params`` and the effects ``eff``."""
    from consistid.errors import TrackingWarning
    from consistid.excitation import FourierTrajectory
    from consistid.simulate import record

    logs = []
    for k, duration in enumerate((30.0, 10.0)):
        traj = FourierTrajectory.random(model, 5, 10.0, seed=int(rng.integers(2 ** 31)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", TrackingWarning)
            rec = record(model, traj, eff, true_parameters=params, duration=duration,
                         rate=500.0, physics_rate=1000.0, seed=10 * seed + k)
        logs.append(ci.Dataset.from_recording(rec.t, rec.q, rec.tau))
    return logs[0], logs[1]


def _mixed_case(arm: str, seed: int, spread: float = 0.12
                ) -> tuple[ci.RobotModel, ci.Dataset, ci.Dataset]:
    """The mixed mismatch of ``benchmarks/diagnosis_mixed.py``: every body perturbed by
    ``±spread`` (0: the nominal bodies, the same draws scaled by 0), Coulomb 0.8–2 N·m and
    viscous 0.3–1.5 N·m·s/rad on every joint, σ = 0.1 N·m; ``(model, train, held)``."""
    from consistid.robot.inertia import perturb
    from consistid.simulate import Effects

    model = ci.RobotModel.example(arm)
    rng = np.random.default_rng(seed)
    params = perturb(model.prior_parameters, spread, rng)
    eff = Effects(coulomb=rng.uniform(0.8, 2.0, model.nv),
                  viscous=rng.uniform(0.3, 1.5, model.nv), torque_noise=0.1)
    return (model, *_train_and_held(model, params, eff, rng, seed))


PAYLOAD_KEPT = pytest.mark.xfail(
    strict=True, raises=AssertionError,
    reason="the selection takes the payload; the consistent fit of every body predicts the "
    "held-out data better on 4 joints (joint2 0.102 → 0.074 N·m) but worse on joint5 (0.117 → "
    "0.124), so the payload is kept with a note: the same trade a payload alone beside "
    "friction shows (test below), which these data cannot tell apart")


@pytest.mark.slow
@pytest.mark.parametrize("arm,seed", [("xarm7", 0), pytest.param("xarm7", 2, marks=PAYLOAD_KEPT),
                                      ("kinova", 2)])
def test_mixed_mismatch_names_inertia_and_reaches_identify(arm, seed):
    """xArm7 and Kinova in MuJoCo, every body's inertia scaled by 0.88–1.12, Coulomb 0.8–2 N·m
    and viscous 0.3–1.5 N·m·s/rad on every joint, σ = 0.1 N·m, 30 s + 10 s at 500 Hz (cases
    where payload or per-joint stand-ins were named instead of inertia; Kinova seed 2 a gain on
    joint 2, the inertia refused while its fit was weighted by each joint's floor; more in
    benchmarks/diagnosis_mixed.py): inertia, Coulomb and viscous friction named, held-out RMS
    per joint ≤ 1.2 × identify(sdp)'s, every joint above 1.5 × its floor flagged. xArm7 seed 2
    is a case where the selection takes the payload (kept: PAYLOAD_KEPT)."""
    model, train, held = _mixed_case(arm, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = ci.diagnose(model, train, held_out=held)
        res = ci.identify(model, train, method="sdp")
    rms_id = np.sqrt(np.mean((held.tau - res.predict(held)) ** 2, axis=0))
    names = {e.name for e in diag.effects}
    assert {"inertia", "coulomb", "viscous"} <= names and "payload" not in names, diag.summary()
    assert np.all(diag.rms_final <= 1.2 * rms_id), (diag.rms_final, rms_id)
    named = set(diag.remainder.flagged) | set(diag.remainder.undetermined)
    above = {n for n, r in zip(model.joint_names, diag.left_to_noise) if r > REMAINDER_RATIO}
    assert above <= named, (diag.verdict, diag.left_to_noise)


@pytest.mark.slow
@pytest.mark.parametrize("arm", ["ur5", "xarm7"])
def test_a_payload_alone_beside_friction_stays_a_payload(arm):
    """A 1 kg payload 5 cm along the last body's z, the nominal bodies otherwise exact, Coulomb
    0.8–2 N·m and viscous 0.3–1.5 N·m·s/rad on every joint, σ = 0.1 N·m, 30 s + 10 s at 500 Hz
    (the review's repro): the payload is named with its mass (the simulated 1 kg within 1 %),
    not every body's inertia, which predicts some joints' held-out data better by soaking up
    friction's model error but one joint worse."""
    from consistid.simulate import Effects

    model = ci.RobotModel.example(arm)
    rng = np.random.default_rng(0)
    params = model.prior_parameters.copy()
    mass, com = 1.0, np.array([0.0, 0.0, 0.05])
    inertia = mass * (com @ com * np.eye(3) - np.outer(com, com)) + 1e-4 * mass * np.eye(3)
    params[-10] += mass
    params[-9:-6] += mass * com
    params[-6:] += inertia[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]
    eff = Effects(coulomb=rng.uniform(0.8, 2.0, model.nv),
                  viscous=rng.uniform(0.3, 1.5, model.nv), torque_noise=0.1)
    logs = _train_and_held(model, params, eff, rng, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = ci.diagnose(model, logs[0], held_out=logs[1])
    names = [e.name for e in diag.effects]
    assert "payload" in names and "inertia" not in names, diag.summary()
    found = diag.effects[names.index("payload")]
    m = next(p for p in found.parameters if p.name.endswith(".m"))
    assert abs(m.value - mass) < 0.01 * mass, m


@pytest.mark.slow
@pytest.mark.parametrize("arm,seed", [("ur5", 0), ("kinova", 1)])
def test_friction_alone_on_exact_bodies_names_no_rigid_body(arm, seed):
    """The nominal bodies exact (the simulation's), Coulomb 0.8–2 N·m and viscous
    0.3–1.5 N·m·s/rad on every joint, σ = 0.1 N·m, 30 s + 10 s at 500 Hz: neither inertia nor
    a payload is named (Kinova seed 1: wrists left 5–7 × their floor by the friction at rest,
    the model error that the inertia, weighted by each joint's residual, must not fit)."""
    from consistid.robot.inertia import perturb

    model, train, held = _mixed_case(arm, seed, spread=0.0)
    # the mixed cases' draws, scaled by 0: the nominal bodies exactly
    np.testing.assert_allclose(perturb(model.prior_parameters, 0.0, np.random.default_rng(seed)),
                               model.prior_parameters)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = ci.diagnose(model, train, held_out=held)
    names = {e.name for e in diag.effects}
    assert not names & {"inertia", "payload"}, diag.summary()
    assert {"coulomb", "viscous"} <= names, diag.summary()


@pytest.mark.slow
def test_a_stand_in_for_part_of_the_inertia_is_not_labelled_high():
    """Kinova seed 1 of the mixed mismatch: with the rigid-body candidates fitted in floor
    weights the selection took a gain on joint 2 as a stand-in for the bodies' inertia and
    labelled it "high"; fitted in the residual's weights, a payload takes joint 2's share
    (the inertia, 36 base parameters, makes joints 3–4 worse on held-out data). Whatever stands
    in, no finding other than inertia, Coulomb or viscous friction (what the simulation has)
    is "high"."""
    model, train, held = _mixed_case("kinova", 1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        diag = ci.diagnose(model, train, held_out=held)
    wrong = [e for e in diag.effects if e.name not in ("inertia", "coulomb", "viscous")]
    assert wrong, diag.summary()                 # the case: a stand-in is named
    assert all(e.confidence != "high" for e in wrong), diag.summary()
