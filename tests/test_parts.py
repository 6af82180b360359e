"""parts.py: the table of the robot's solid parts, checked against the kinematic layout it is
built around (sizes, gaps and placements its docstring states)."""

import numpy as np

from stewart_drake.robot import parts
from stewart_drake.robot.geometry import StewartGeometry
from stewart_drake.robot.statics import p_ETool


def _by_name(geometry):
    return {(p.link, p.name): p for p in parts.robot_parts(geometry)}


def test_every_part_is_named_once_in_sdf_link_order(geometry):
    table = parts.robot_parts(geometry)
    names = [(p.link, p.name) for p in table]
    assert len(names) == len(set(names))
    links = list(dict.fromkeys(p.link for p in table))
    assert links == ["base"] + [f"{k}_{i}" for i in range(6) for k in ("crank", "rod")] + [
        "platform"
    ]
    for p in table:
        np.testing.assert_allclose(p.R_LG.T @ p.R_LG, np.eye(3), atol=1e-12)
        assert np.linalg.det(p.R_LG) > 0 and all(v > 0 for v in p.size)
    # the studs touch their rod ends by design: drawn, never collision geometry
    assert {p.name for p in table if not p.collides} == {f"stud_{i}" for i in range(6)}
    assert {p.family for p in table} >= {"rod tube", "rod end_top", "base motor", "crank arm"}


def test_a_rod_s_tube_stops_tube_gap_short_of_its_ends(geometry):
    """The capsule (cylinder length + 2 radii) runs from rod_end_radius + TUBE_GAP above the
    crank tip to as far below the platform joint, along the rod's z."""
    table = _by_name(geometry)
    s = geometry.rod_length
    for i in range(6):
        tube = table[(f"rod_{i}", "tube")]
        radius, length = tube.size
        assert radius == geometry.rod_radius
        bottom = tube.p_LG[2] - length / 2 - radius
        top = tube.p_LG[2] + length / 2 + radius
        assert np.isclose(bottom, geometry.rod_end_radius + parts.TUBE_GAP, atol=1e-15)
        assert np.isclose(s - top, geometry.rod_end_radius + parts.TUBE_GAP, atol=1e-15)
        np.testing.assert_array_equal(table[(f"rod_{i}", "end_top")].p_LG, [0, 0, s])
        np.testing.assert_array_equal(table[(f"rod_{i}", "end_bottom")].p_LG, [0, 0, 0])


def test_the_plate_sits_platform_gap_above_the_rod_ends_and_the_tool_reaches_its_tip(geometry):
    table = _by_name(geometry)
    plate = table[("platform", "plate")]
    plate_bottom = plate.p_LG[2] - plate.size[1] / 2
    assert np.isclose(plate_bottom - geometry.rod_end_radius, parts.PLATFORM_GAP, atol=1e-15)
    assert np.all(np.linalg.norm(geometry.p_E[:, :2], axis=1) < plate.size[0])  # ends under it
    tool = table[("platform", "tool")]
    assert np.isclose(tool.p_LG[2] + tool.size[1] / 2, p_ETool[2], atol=1e-15)
    assert np.isclose(
        tool.p_LG[2] - tool.size[1] / 2, plate.p_LG[2] + plate.size[1] / 2, atol=1e-15
    )  # on the plate


def test_each_motor_sits_outboard_on_its_shaft_beyond_its_bracket(geometry):
    o = parts.motor_outward(geometry)
    np.testing.assert_allclose(np.linalg.norm(o, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(np.abs(np.sum(o * geometry.u_B, axis=1)), 1.0, atol=1e-15)
    assert np.all(np.sum(o * geometry.P_B, axis=1) > 0)
    table = _by_name(geometry)
    for i in range(6):
        motor = table[("base", f"motor_{i}")]
        along = (motor.p_LG - geometry.P_B[i]) @ o[i]
        assert np.isclose(
            along,
            parts.BRACKET_OFFSET + parts.BRACKET_THICKNESS + parts.MOTOR_LENGTH / 2,
            atol=1e-15,
        )
        np.testing.assert_allclose(motor.R_LG[:, 2], o[i], atol=1e-15)  # axis on the shaft


def test_the_part_sizes_follow_the_geometry():
    g = StewartGeometry(rod_radius=0.004, rod_end_radius=0.008, platform_plate_radius=0.14)
    table = _by_name(g)
    assert table[("rod_3", "tube")].size[0] == 0.004
    assert table[("rod_3", "end_top")].size == (0.008,)
    assert table[("platform", "plate")].size[0] == 0.14


def test_a_bracket_reaches_its_motor_from_the_arm_whether_the_shafts_sit_low_or_high():
    """Below the plate the bracket hangs from the arm's underside to under the motor; with the
    shafts high (a design's home height under 0.30 m) it stands on the arm's top face and
    spans the motor's housing. Every size is positive (a negative one became a 1 m box in
    Drake's SDF parser)."""
    from stewart_drake.design.variables import Design

    for home_height, above in ((0.37, False), (0.25, True), (0.20, True)):
        design = Design(home_height=home_height)
        lo, hi = design.rod_length_range()
        design.rod_length = 0.5 * (lo + hi)
        g = design.geometry()
        for part in parts.robot_parts(g):
            assert min(part.size) > 0, (home_height, part.name, part.size)
        for i in range(6):
            bracket = _by_name(g)[("base", f"bracket_{i}")]
            z_lo = bracket.p_LG[2] - bracket.size[2] / 2
            z_hi = bracket.p_LG[2] + bracket.size[2] / 2
            shaft_z = g.P_B[i, 2]
            if above:  # on the arm's top face, up past the motor's housing
                assert np.isclose(z_lo, 0.0) and z_hi >= shaft_z + parts.MOTOR_RADIUS
            else:  # under the arm, down past the motor's housing
                assert np.isclose(z_hi, -parts.BASE_THICKNESS)
                assert z_lo <= shaft_z - parts.MOTOR_RADIUS
