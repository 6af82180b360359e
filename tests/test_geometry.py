import numpy as np
import pytest

from stewart_drake.base.errors import InvalidGeometryError
from stewart_drake.robot.geometry import (
    TABLE_I_CRANK_INERTIA,
    StewartGeometry,
    nearest_valid_principal_moments,
)


def test_default_is_reference_geometry(geometry):
    np.testing.assert_allclose(geometry.pivot_angles_deg, [-10, 10, 110, 130, 230, 250])
    np.testing.assert_allclose(geometry.platform_angles_deg, [-55, 55, 65, 175, 185, 295])
    np.testing.assert_allclose(geometry.crank_angles_deg, [-90, 90, 30, 210, 150, 330])
    np.testing.assert_allclose(
        geometry.P_B[1], 0.2 * np.array([np.cos(np.pi / 18), np.sin(np.pi / 18), 0]) + [0, 0, -0.07]
    )
    np.testing.assert_allclose(geometry.u_B, np.cross(geometry.d_B, [0, 0, 1]))
    assert (geometry.crank_length, geometry.rod_length) == (0.11, 0.404)


def test_crank_inertia_is_nearest_valid_tensor():
    fixed = np.array(nearest_valid_principal_moments(TABLE_I_CRANK_INERTIA))
    a, b, c = fixed
    assert a + b >= c
    # Nearest: the change is along (1, 1, -1) and as small as the deficit requires.
    delta = fixed - TABLE_I_CRANK_INERTIA
    np.testing.assert_allclose(delta / delta[0], [1, 1, -1])
    assert np.linalg.norm(delta) < 1e-6
    assert StewartGeometry().crank_inertia == tuple(fixed)


def test_invalid_inertia_is_rejected_with_the_fix():
    with pytest.raises(InvalidGeometryError, match="nearest valid"):
        StewartGeometry(crank_inertia=TABLE_I_CRANK_INERTIA)


@pytest.mark.parametrize(
    "change",
    [
        dict(rod_length=-1),
        dict(crank_length=0),
        dict(rod_length=0.1),
        dict(platform_mass=float("nan")),
        dict(rod_length=0.9),
    ],
)
def test_bad_geometry_raises(change):
    with pytest.raises(InvalidGeometryError):
        StewartGeometry(**change)


def test_the_geometry_has_every_attribute_the_model_functions_read():
    """kinematics, limits and statics annotate the robot with the structural type
    RobotGeometry (they sit below the geometry): each of its attributes is a field of
    StewartGeometry of the same kind, or one of its derived anchors."""
    import functools
    import typing

    from stewart_drake.robot.kinematics import RobotGeometry

    assert isinstance(StewartGeometry(), RobotGeometry)
    fields = typing.get_type_hints(StewartGeometry)
    for name, kind in typing.get_type_hints(RobotGeometry).items():
        if name in fields:
            assert (typing.get_origin(fields[name]) or fields[name]) is kind, name
        else:
            assert isinstance(getattr(StewartGeometry, name), functools.cached_property), name


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("platform_mass", 1e308, r"platform_mass must be a finite number in \(0, 100000\]"),
        ("rod_mass", 2e5, r"rod_mass must be a finite number in \(0, 100000\]"),
        ("rod_length", 1e3, r"rod_length must be a finite number in \(0, 100\]"),
        ("base_radius", float("inf"), "base_radius must be a finite number"),
    ],
)
def test_a_length_or_mass_beyond_any_robot_is_refused_naming_it(field, value, words):
    with pytest.raises(InvalidGeometryError, match=words):
        StewartGeometry(**{field: value})


def test_the_largest_mass_and_length_allowed_are_taken():
    robot = StewartGeometry(platform_mass=1e5, base_mass=1e5)
    assert robot.platform_mass == 1e5 and robot.base_mass == 1e5
