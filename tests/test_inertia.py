"""InertialParameters: one body's standard parameters as a value, checked against Pinocchio."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from consistid.errors import InconsistentParametersError, ParameterShapeError
from consistid.robot.inertia import InertialParameters, bodies, body_slice

finite = st.floats(-1.0, 1.0, allow_nan=False)


@st.composite
def solid_bodies(draw) -> pin.Inertia:
    """A random solid body: positive mass, any CoM, principal moments obeying the triangle
    inequalities strictly, any orientation."""
    mass = draw(st.floats(0.05, 20.0))
    com = np.array([draw(finite) for _ in range(3)])
    a, b, c = (draw(st.floats(0.05, 1.0)) for _ in range(3))  # semi-axes of a solid ellipsoid
    moments = mass / 5 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    rotation = pin.utils.rpyToMatrix(*(draw(st.floats(-3.0, 3.0)) for _ in range(3)))
    return pin.Inertia(mass, com, rotation @ np.diag(moments) @ rotation.T)


@given(solid_bodies())
@settings(max_examples=60, deadline=None)
def test_views_agree_with_pinocchio(inertia):
    body = InertialParameters.from_pinocchio(inertia)
    assert body.mass == pytest.approx(inertia.mass)
    np.testing.assert_allclose(body.com, inertia.lever, atol=1e-12)
    np.testing.assert_allclose(body.inertia_com, inertia.inertia, atol=1e-12)
    np.testing.assert_allclose(body.J, pin.PseudoInertia.FromInertia(inertia).toMatrix(),
                               atol=1e-12)
    assert body.consistent().ok and np.linalg.eigvalsh(body.J)[0] > 0


@given(solid_bodies())
@settings(max_examples=60, deadline=None)
def test_constructors_round_trip(inertia):
    body = InertialParameters.from_pinocchio(inertia)
    again = InertialParameters.from_mass_com_inertia(body.mass, body.com, body.inertia_com)
    np.testing.assert_allclose(again.vector, body.vector, atol=1e-12)
    np.testing.assert_allclose(InertialParameters.from_pseudo_inertia(body.J).vector,
                               body.vector, atol=1e-12)
    np.testing.assert_allclose(body.to_pinocchio().toDynamicParameters(), body.vector, atol=1e-12)


@given(solid_bodies(), st.tuples(finite, finite, finite), st.tuples(finite, finite, finite))
@settings(max_examples=60, deadline=None)
def test_transform_is_pinocchios_se3_action(inertia, rpy, translation):
    rotation = pin.utils.rpyToMatrix(*rpy)
    moved = InertialParameters.from_pinocchio(inertia).transform(rotation, translation)
    expected = pin.SE3(rotation, np.array(translation)).act(inertia).toDynamicParameters()
    np.testing.assert_allclose(moved.vector, expected, atol=1e-10)
    assert moved.mass == pytest.approx(inertia.mass)


@given(solid_bodies(), solid_bodies())
@settings(max_examples=40, deadline=None)
def test_sum_is_the_joined_body(a, b):
    joined = InertialParameters.from_pinocchio(a) + InertialParameters.from_pinocchio(b)
    np.testing.assert_allclose(joined.vector, (a + b).toDynamicParameters(), atol=1e-10)


def test_split_and_bodies_are_the_per_body_rows(panda):
    theta = panda.prior_parameters
    parts = InertialParameters.split(theta, panda.n_bodies)
    assert len(parts) == panda.n_bodies
    for i, part in enumerate(parts):
        np.testing.assert_array_equal(part.vector, theta[body_slice(i)])
        assert part.mass == pytest.approx(panda.pin_model.inertias[i + 1].mass)
    view = bodies(theta.copy())
    view[2, 0] = 99.0
    assert view.base is not None and view.shape == (panda.n_bodies, 10)


def test_value_semantics_and_named_errors():
    v = np.arange(10.0) + 1
    body = InertialParameters(v)
    v[0] = -5.0  # the value took a copy
    assert body.mass == 1.0
    with pytest.raises(ValueError):
        body.vector[0] = 3.0
    assert body == InertialParameters(np.arange(10.0) + 1) and len({body, body}) == 1
    with pytest.raises(ParameterShapeError, match=r"\(10,\)"):
        InertialParameters(np.zeros(9))
    with pytest.raises(InconsistentParametersError, match="finite"):
        InertialParameters(np.r_[np.nan, np.zeros(9)])
    with pytest.raises(InconsistentParametersError, match="mass"):
        InertialParameters(np.zeros(10)).com
    assert not InertialParameters(np.r_[-1.0, np.zeros(9)]).consistent().ok
    with pytest.raises(ParameterShapeError, match="10 per body"):
        bodies(np.zeros(15))
