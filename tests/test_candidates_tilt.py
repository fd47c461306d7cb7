"""The ``tilt`` candidate of the diagnosis: its columns are the first-order torque change of a
tilted gravity, and a tilted robot diagnosed against the level model is named ``tilt`` with its
angles; a level robot with wrong inertias is not."""

from __future__ import annotations

import numpy as np
import pytest

from consistid.robot.inertia import perturb
from consistid.diagnosis.candidates import EffectLibrary, GapData
from consistid.diagnosis.diagnose import diagnose
from consistid.estimation.mounting import gravity_from_tilt
from consistid.identification.regressor import rigid_body_regressor
from consistid.simulate import excitation_run

RATE = 200.0


@pytest.mark.parametrize("gravity", [(0.0, 0.0, -9.81), (0.0, -9.81, 0.0)])
def test_tilt_columns_are_the_first_order_torque_change(panda, gravity):
    """``Y(q, 0, 0; g(a)) π₀ − Y(q, 0, 0; g₀) π₀ = Φ a + O(|a|²)``, with ``g(a)`` the exact
    rotation of :func:`gravity_from_tilt`: the error falls 100-fold when the angles do 10-fold."""
    model = panda.with_gravity(gravity)
    ds = excitation_run(model, duration=2.0, rate=50.0, torque_noise=0.0, seed=3).dataset
    lib = EffectLibrary(model, ("tilt",))
    (atom,) = lib.atoms()
    assert atom.parameter_names == ("tilt.roll", "tilt.pitch") and atom.units == ("rad", "rad")
    phi = lib.columns(atom, GapData(model, ds, model.prior_parameters))
    zero = np.zeros_like(ds.dq)

    def gravity_torque(g: np.ndarray) -> np.ndarray:
        y = rigid_body_regressor(model.with_gravity(g), ds.q, zero, zero)
        return y @ model.prior_parameters

    level = gravity_torque(model.gravity)
    errors = []
    for scale in (1e-2, 1e-3):
        a = scale * np.array([0.8, -0.6])
        change = gravity_torque(gravity_from_tilt(model.gravity, a)) - level
        errors.append(np.max(np.abs(change - phi @ a)))
        assert errors[-1] < 0.02 * np.max(np.abs(change))
    assert errors[0] / errors[1] == pytest.approx(100.0, rel=0.05)


def _runs(model, parameters=None):
    return [excitation_run(model, parameters, duration=d, rate=RATE, torque_noise=0.1,
                           seed=s).dataset for s, d in ((1, 10.0), (2, 6.0))]


def test_tilted_robot_is_named_tilt_with_its_angles(panda):
    truth = np.radians([1.0, -0.7])
    train, held = _runs(panda.with_gravity(gravity_from_tilt(panda.gravity, truth)))
    diag = diagnose(panda, train, held_out=held)
    assert [e.name for e in diag.effects] == ["tilt"], [str(e) for e in diag.effects]
    (found,) = diag.effects
    assert found.scope == "arm" and found.total_shrink > 0.5
    for p, a in zip(found.parameters, truth):
        assert p.unit == "rad"
        assert abs(p.value - a) < max(4 * p.std, 0.05 * abs(a)), (p, a)
    assert str(found.parameters[0]).startswith("tilt.roll 1.0") and "°" in str(found.parameters[0])
    assert diag.at_noise_floor


def test_level_robot_with_wrong_inertias_is_not_named_tilt(panda):
    """Part of a tilt lies in the span of ``inertia``; a pure rigid-body mismatch must not be
    reported as a tilt. (A level robot without any mismatch names nothing at all:
    ``test_diagnose.test_no_effect_names_nothing_and_is_at_the_noise_floor``.)"""
    params = perturb(panda.prior_parameters, 0.2, np.random.default_rng(3))
    train, held = _runs(panda, params)
    diag = diagnose(panda, train, held_out=held)
    assert [e.name for e in diag.effects] == ["inertia"], [str(e) for e in diag.effects]
