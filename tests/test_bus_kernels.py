"""The servo-bus station's compiled period (stewart_drake/station/bus/kernels.py): the pose and
the plant state against the numpy forms they replace, the bus's packets against the vendor's
library byte for byte, the compiled against the interpreted code, and no compilation left for a
control period to pay."""

import hashlib
import math

import numpy as np
import pytest
from conftest import require_extra

require_extra("robot")

import dynamixel_sdk as sdk  # noqa: E402, I001

from stewart_drake.plant.closed_chain import assembled_positions  # noqa: E402
from stewart_drake.robot.kinematics import X_HOME, ik, jacobian  # noqa: E402
from stewart_drake.robot.kinematics import angular_velocity_map  # noqa: E402
from stewart_drake.robot.single_pose import ik_single, jacobian_single  # noqa: E402
from stewart_drake.run.plan import make_plan  # noqa: E402
from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario  # noqa: E402
from stewart_drake.station.bus import kernels, servos  # noqa: E402
from stewart_drake.station.bus import protocol as p  # noqa: E402
from stewart_drake.station.bus.measured_state import MeasuredPlantState  # noqa: E402
from stewart_drake.station.bus.station import HardwareStation  # noqa: E402

TABLE = np.array(p._CRC_TABLE, dtype=np.uint16)
IDS = np.array([1, 2, 3, 4, 5, 6], dtype=np.int64)


@pytest.fixture(scope="module")
def station():
    return HardwareStation(make_plan(load_scenario(ROBOT_SCENARIO)))


def _poses(n, seed=0):
    rng = np.random.default_rng(seed)
    x = X_HOME + rng.uniform(-1, 1, (n, 6)) * [0.1, 0.1, 0.1, 0.02, 0.02, 0.02]
    x_dot = rng.normal(size=(n, 6)) * [0.5, 0.5, 0.5, 0.05, 0.05, 0.05]
    return x, x_dot


def test_the_plant_state_is_the_numpy_assembly_with_its_rates(station):
    plant, handles = station.plant, station.handles
    measured = MeasuredPlantState(plant, handles)
    nq = plant.num_positions()
    iv = nq + handles.platform.floating_velocities_start_in_v()
    motors_v = [nq + j.velocity_start() for j in handles.motors]
    for x, x_dot in zip(*_poses(50)):
        out = np.zeros(nq + plant.num_velocities())
        kernels.plant_state(
            measured._legs, measured._u_B, measured._R0, measured._layout, np.r_[x, x_dot], out
        )
        expected = np.zeros_like(out)
        expected[:nq] = assembled_positions(plant, handles, x)
        expected[iv : iv + 3] = angular_velocity_map(x[:3]) @ x_dot[:3]
        expected[iv + 3 : iv + 6] = x_dot[3:]
        expected[motors_v] = jacobian(handles.geometry, x) @ x_dot
        np.testing.assert_allclose(out, expected, rtol=0, atol=1e-12)


def test_the_measured_pose_is_the_estimators_newton_and_its_rate_j_inverse_theta_dot(station):
    estimator = station.driver._fk
    geometry = station.plan.geometry
    for x, x_dot in zip(*_poses(50, seed=1)):
        theta = ik(geometry, x)
        theta_dot = jacobian(geometry, x) @ x_dot
        out = np.zeros(12)
        assert kernels.measure_pose(
            estimator.legs,
            estimator.mode,
            estimator.tol,
            estimator.max_iterations,
            X_HOME.copy(),
            theta,
            theta_dot,
            out,
        )
        newton, _, converged = estimator.estimate(theta, X_HOME)
        assert converged
        np.testing.assert_allclose(out[:6], newton, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ik(geometry, out[:6]), theta, atol=0.01 * 2 * np.pi / 4096)
        _, cache = ik_single(geometry, newton)
        rate = np.linalg.solve(jacobian_single(geometry, cache), theta_dot)
        np.testing.assert_allclose(out[6:], rate, rtol=1e-10, atol=1e-12)
    # Angles that are no pose: not converged, and the caller falls back on the full FK.
    assert not kernels.measure_pose(
        estimator.legs, estimator.mode, estimator.tol, 20, X_HOME.copy(), np.full(6, 3.0),
        np.zeros(6), np.zeros(12),
    )  # fmt: skip


def test_the_compiled_kernels_are_their_interpreted_source_to_the_bit(station):
    measured = MeasuredPlantState(station.plant, station.handles)
    estimator = station.driver._fk
    geometry = station.plan.geometry
    n = station.plant.num_positions() + station.plant.num_velocities()
    for x, x_dot in zip(*_poses(10, seed=2)):
        args = (measured._legs, measured._u_B, measured._R0, measured._layout, np.r_[x, x_dot])
        a, b = np.zeros(n), np.zeros(n)
        kernels.plant_state(*args, a)
        kernels.reference.plant_state(*args, b)
        assert a.tobytes() == b.tobytes()
        fk = (estimator.legs, estimator.mode, estimator.tol, 20, X_HOME.copy(), ik(geometry, x))
        a, b = np.zeros(12), np.zeros(12)
        kernels.measure_pose(*fk, x_dot, a)
        kernels.reference.measure_pose(*fk, x_dot, b)
        assert a.tobytes() == b.tobytes()


def _sync_write_packet(units):
    params = p.GOAL_CURRENT[0].to_bytes(2, "little") + (2).to_bytes(2, "little")
    params += b"".join(bytes([i, 0, 0]) for i in IDS)
    packet = np.frombuffer(p.build_packet(p.BROADCAST_ID, p.SYNC_WRITE, params), np.uint8).copy()
    kernels.fill_sync_write(TABLE, packet, np.asarray(units, dtype=np.int64))
    return bytes(packet)


class _Capture(sdk.PortHandler):
    """A port that keeps the last packet the vendor's library sent."""

    def __init__(self):
        self.is_using, self.sent = False, b""

    def clearPort(self):  # noqa: N802 - the SDK's name
        pass

    def writePort(self, packet):  # noqa: N802
        self.sent = bytes(packet)
        return len(packet)


def test_the_goals_sync_write_is_the_vendors_byte_for_byte_and_stuffed_by_the_driver():
    """Profile Velocity and Goal Position (XM430's 112 and 116, four bytes each) for six servos,
    goals of both signs and the counts' extremes: the compiled packet is the vendor's. Values
    whose bytes hold FF FF FD (a profile of 0xFDFFFF units, a goal of 0x7FFDFFFF counts) are
    refused by the kernel, and the driver's rebuild, :func:`~.protocol.build_packet` of the
    parameters the kernel wrote, is stuffed as Protocol 2.0 says: one FD more after the FF FF FD,
    counted in the length, under its CRC, and unstuffed it is the vendor's parameters. (The
    vendor's Python library 4.1 sends such a packet unstuffed: its ``txPacket`` drops what
    ``addStuffing`` returns when the length grows, so its bytes are not the reference there.)"""
    address = servos.servo_spec("XM430-W350-T").table.profile_velocity[0]
    assert address == 112  # the e-Manual's
    rng = np.random.default_rng(5)
    cases = [
        ([0] * 6, [0] * 6, True),
        ([1, 0xFF, 0x100, 7, 0xFFFF, 2], [-1, 4095, -4096, 2048, -(2**31), 2**31 - 1], True),
        (rng.integers(1, 2000, 6), rng.integers(-(2**20), 2**20, 6), True),
        ([0xFDFFFF, 1, 1, 1, 1, 1], [0] * 6, False),
        ([1] * 6, [0, 0, 0x7FFDFFFF, 0, 0, 0], False),
    ]
    for profile, goal, plain in cases:
        port = _Capture()
        group = sdk.GroupSyncWrite(port, sdk.PacketHandler(2.0), address, 8)
        for i, u, c in zip(IDS, profile, goal):
            data = int(u).to_bytes(4, "little") + p.to_unsigned(int(c), 4).to_bytes(4, "little")
            group.addParam(int(i), list(data))
        assert group.txPacket() == sdk.COMM_SUCCESS
        params = address.to_bytes(2, "little") + (8).to_bytes(2, "little")
        params += b"".join(bytes([i]) + bytes(8) for i in IDS)
        packet = np.frombuffer(p.build_packet(p.BROADCAST_ID, p.SYNC_WRITE, params), np.uint8)
        packet = packet.copy()
        units, counts = (np.asarray(v, dtype=np.int64) for v in (profile, goal))
        assert kernels.fill_goal_write(TABLE, packet, units, counts) is plain
        if plain:
            assert bytes(packet) == port.sent
            continue
        rebuilt = p.build_packet(p.BROADCAST_ID, p.SYNC_WRITE, packet[8:-2].tobytes())
        assert len(rebuilt) == packet.size + 1
        assert int.from_bytes(rebuilt[5:7], "little") == len(rebuilt) - 7
        body = rebuilt[7:]
        assert body.count(b"\xff\xff\xfd") == body.count(b"\xff\xff\xfd\xfd") == 1
        parsed, used, crc_ok = p.parse_packet(rebuilt)
        assert crc_ok and used == len(rebuilt)
        assert bytes([parsed.instruction]) + parsed.params == port.sent[7:-2]


def test_the_sync_write_is_the_vendors_byte_for_byte():
    rng = np.random.default_rng(3)
    for units in ([0] * 6, [-1193, 1193, -1, 1, 0xFF, -0x100], rng.integers(-1193, 1194, 6)):
        port = _Capture()
        group = sdk.GroupSyncWrite(port, sdk.PacketHandler(2.0), *p.GOAL_CURRENT)
        for i, u in zip(IDS, units):
            group.addParam(int(i), list(p.to_unsigned(int(u), 2).to_bytes(2, "little")))
        assert group.txPacket() == sdk.COMM_SUCCESS
        assert _sync_write_packet(units) == port.sent


def test_status_packets_are_parsed_as_they_arrive_stuffed_or_corrupt():
    rng = np.random.default_rng(4)
    raw = np.column_stack(
        [rng.integers(-1193, 1194, 6), rng.integers(-2000, 2001, 6), rng.integers(-9000, 9000, 6)]
    )
    raw[2] = [-3, -513, 0x00FDFFFF]  # data bytes FF FF FD: a stuffed packet
    replies = b"".join(
        p.build_status(
            int(i),
            0x80 if k == 1 else 0,  # an Alert bit: not read, as the vendor's sync read
            b"".join(
                p.to_unsigned(int(v), size).to_bytes(size, "little")
                for v, size in zip(raw[k], (2, 4, 4))
            ),
        )
        for k, i in enumerate(IDS[::-1][np.argsort(IDS[::-1])])  # any order on the wire
    )
    assert len(replies) > 6 * 21  # FD stuffed after FF FF FD
    stream = b"\x00\xff" + replies  # junk before the first header
    buf = np.zeros(len(stream), dtype=np.uint8)
    found, values = np.zeros(6, dtype=bool), np.zeros((6, 3))
    for cut in (0, 5, 30, 60, len(stream) - 1):  # bytes arriving in pieces
        buf[:cut] = np.frombuffer(stream[:cut], np.uint8)
        count = kernels.parse_status(TABLE, buf, cut, IDS, found, values)
        assert count == found.sum() < 6
    buf[:] = np.frombuffer(stream, np.uint8)
    assert kernels.parse_status(TABLE, buf, len(stream), IDS, found, values) == 6
    np.testing.assert_array_equal(values, raw)
    bad = buf.copy()
    bad[35] ^= 0x10  # inside the second packet's data (its header starts at 23)
    assert kernels.parse_status(TABLE, bad, len(stream), IDS, np.zeros(6, bool), values) == -1


def test_the_conversions_are_the_numpy_ones_to_the_bit():
    spec = servos.SERVO_SPECS["XM430-W350-T"]
    rng = np.random.default_rng(5)
    sign = np.array([1.0, -1.0, 1.0, 1.0, -1.0, 1.0])
    zero = np.array([2048, 2000, 100, 4095, 0, 3000], dtype=float)
    raw = np.column_stack(
        [rng.integers(-1193, 1194, 6), rng.integers(-2000, 2001, 6), rng.integers(-9000, 9000, 6)]
    ).astype(float)
    out = np.zeros((3, 6))
    kt, unit = spec.torque_constant_Nm_per_A, spec.amps_per_unit
    kernels.crank_state(raw, zero, sign, 2 * math.pi / 4096, p.VELOCITY_UNIT_RAD_S, kt, unit, out)
    assert out[0].tobytes() == p.counts_to_rad(raw[:, 2], zero, sign).tobytes()
    assert out[1].tobytes() == p.velocity_units_to_rad_s(raw[:, 1], sign).tobytes()
    assert out[2].tobytes() == servos.current_units_to_torque(raw[:, 0], spec, sign).tobytes()
    tau = rng.normal(size=6) * 3
    tau[0] = 0.5 * unit * kt  # half a unit: rounds to even, as numpy's rint
    units, applied = np.zeros(6, dtype=np.int64), np.zeros(6)
    assert kernels.torque_command(tau, sign, kt, unit, 400, units, applied)
    expected = np.clip(servos.torque_to_current_units(tau, spec, sign), -400, 400)
    np.testing.assert_array_equal(units, expected)
    assert applied.tobytes() == servos.current_units_to_torque(expected, spec, sign).tobytes()
    assert not kernels.torque_command(np.r_[np.nan, tau[1:]], sign, kt, unit, 400, units, applied)


def test_the_path_kernels_digest_is_the_one_the_cache_was_built_against():
    """The bus kernels compile in functions of robot/path_kernels.py, whose changes numba's
    cache does not see: the cache is used while this digest is the one recorded."""
    from stewart_drake.robot import path_kernels

    digest = hashlib.sha256(open(path_kernels.__file__, "rb").read()).hexdigest()[:16]
    assert digest == path_kernels.source_digest() == kernels.PATH_KERNELS_DIGEST, (
        f"set PATH_KERNELS_DIGEST = {digest!r} in stewart_drake/station/bus/kernels.py"
    )
