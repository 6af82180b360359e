"""The servo's own position loop on servos as they are: a study of what a controller that
streams goal positions would make, before the bus carries it.

Each shipped bus robot's breathing on the realistic emulator's robot (``emulator:`` of the
scenario, drawn from its seed: :class:`~stewart_drake.live.plant_backend.RealisticServos`, the
plant at 1 ms), its servos each running their firmware's Position Control Mode
(:class:`~stewart_drake.station.bus.servo_firmware.PositionFirmware`: the profile, a PID with
velocity feed-forward whose output is the PWM, at the firmware's own 1 ms, on its own encoder)
on the goals a host streams every control period: each the reference's crank angles (inverse
kinematics) for the time its profile reaches it, one period after it arrives, with the Profile
Velocity that reaches it then. The bus is a fixed delay between the host's instant and
the servo's having the goal (``--bus-delay-ms``, 3 ms: the realistic bus's median read, measured
in docs/robot.md) and no protocol: the host current loop's figures beside it
(``servo_departures.py``, docs/robot.md's table) come from whole sessions over the emulated bus.

Each row: the true pose (the plant's) against the reference, RMS / peak per axis after the first
``--skip`` s, whether it ran to its end with the true X's peak within 1 mm (a loop that broke
into oscillation does not), the wall time. The firmware's gains (``--position-hz``,
``--damping``) are placed on the catalogue's servo, the nominal supply and the crank's share of
the platform (:func:`~stewart_drake.station.bus.servo_firmware.position_gains`); the servos
behind them are the draw's.

Usage: python benchmarks/servo_position_loop.py [--scenario phantom_bus paper_bus]
    [--duration 20] [--skip 8] [--velocity-hz 30] [--position-hz 8] [--markdown FILE]
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bus_accuracy import AXES, reference_of  # noqa: E402
from servo_departures import ROWS as DEPARTURES  # noqa: E402

#: ideal, the realistic default and its edges of kt and rotor: servo_departures.py's first rows.
ROWS = DEPARTURES[:6]


def run(scenario_name: str, settings: list[str], args) -> dict:
    """One run: {true: (rms (6,), peak (6,)), within (it ran to its end, its true X's peak
    within 1 mm), wall_s}."""
    from stewart_drake.live.plant_backend import (
        RealisticServos,
        StationServos,
        behind_the_bus,
        dynamixel_scenario,
    )
    from stewart_drake.robot.kinematics import ik
    from stewart_drake.robot.motor_catalogue import catalogue_motor
    from stewart_drake.run.plan import run_reference
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.station.bus.protocol import SUPPLY_V
    from stewart_drake.station.bus.servo_firmware import PositionFirmware, position_gains
    from stewart_drake.station.bus.servo_physics import limited_duty, pwm_current
    from stewart_drake.station.bus.servos import servo_spec

    scenario = load_scenario(scenario_name, settings)
    scenario.reference = reference_of("breathing", [])
    scenario.duration_s = args.duration
    model = scenario.bus.model
    spec = servo_spec(model, torque_control=False)
    servos = scenario.emulator.draw(spec, 6)
    reference = run_reference(scenario)
    geometry = scenario.robot.build()
    h, period = 1e-3, scenario.control_period_s
    x0 = reference.evaluate(np.array([0.0]))[0][0]
    behind = behind_the_bus(scenario, servos)
    behind.plant.time_step = h
    robot = dynamixel_scenario(model, behind)
    if servos.departs():
        plant = RealisticServos(robot, model, x0, servos)
    else:
        plant = StationServos(robot, model, x0)
    # the firmware's gains from what the host believes: the catalogue's servo, the nominal supply
    supply = SUPPLY_V[spec.table.family]
    k_model = spec.torque_constant_Nm_per_A
    r_model = supply / spec.stall_current_A
    share = (geometry.platform_mass / 6 + geometry.rod_mass) * geometry.crank_length**2
    inertia = catalogue_motor(model).servo.reflected_inertia + share
    gains = position_gains(inertia, k_model, r_model, supply, args.position_hz, args.damping)
    firmware = PositionFirmware(gains, spec.rad_per_count, plant.positions_rad())
    # the servos as they are: their own constant, winding and supply drive the duty
    k, r = servos.k_Nm_per_A, servos.resistance_ohm
    v_supply = servos.supply_V if np.isfinite(servos.supply_V) else supply
    limit = spec.current_limit_max * spec.amps_per_unit
    # the host's goals, one a period, each reached one period after it arrives (its profile)
    delay = args.bus_delay_ms * 1e-3
    t_host = np.arange(0.0, args.duration, period)
    theta = ik(geometry, reference.evaluate(t_host + delay + period)[0])
    profile = np.abs(np.diff(theta, axis=0, prepend=theta[:1])) / period
    station = plant.station
    port = station.GetOutputPort("platform_state")
    context = station.GetMyContextFromRoot(plant.simulator.get_context())
    motors = plant.station.handles.motors
    n = round(args.duration / h)
    steps_per_period = round(period / h)
    arrive = round(delay / h)
    t_log, x_log = [], []
    start = time.perf_counter()
    for j in range(n):
        p, rem = divmod(j - arrive, steps_per_period)
        if j >= arrive and rem == 0 and p < len(t_host):
            firmware.set_goal(theta[p], profile[p] if p else None)
        duty = firmware.duty(plant.positions_rad())
        v = [m.get_angular_rate(plant._plant_context) for m in motors]
        current = np.array([
            pwm_current(limited_duty(duty[i], v[i], v_supply, k[i], r[i], limit, 1.0), v[i],
                        v_supply, k[i], r[i])
            for i in range(6)
        ])  # fmt: skip
        try:
            plant.advance(h, current)
        except RuntimeError:  # the closed chain left its workspace: an unstable loop
            break
        if j % 5 == 4:
            t_log.append((j + 1) * h)
            x_log.append(port.Eval(context)[:6].copy())
            if np.max(np.abs(x_log[-1][3:] - x0[3:])) > 0.05:
                break  # the platform left: an unstable loop
    wall = time.perf_counter() - start
    t_log, x_log = np.array(t_log), np.array(x_log)
    keep = t_log >= args.skip
    e = x_log[keep] - reference.evaluate(t_log[keep])[0]
    rms, peak = np.sqrt(np.mean(e**2, axis=0)), np.max(np.abs(e), axis=0)
    ran = t_log[-1] >= args.duration - h
    return {"true": (rms, peak), "within": bool(ran and peak[3] < 1e-3), "wall_s": wall}


def lines(name: str, rows: list[tuple[str, dict]]) -> list[str]:
    """The rows as a Markdown table, RMS / peak (urad, um)."""
    from stewart_drake.base.tables import markdown_lines

    head = ["emulator", *(f"{a} {'urad' if k < 3 else 'um'}" for k, a in enumerate(AXES))]
    body = []
    for label, r in rows:
        rms, peak = r["true"]
        cells = [f"{1e6 * a:.0f} / {1e6 * b:.0f}" for a, b in zip(rms, peak, strict=True)]
        body.append([label, *cells, "yes" if r["within"] else "**no**"])
    return [f"**{name}**, servo position loop, true pose RMS / peak:", ""] + markdown_lines(
        [*head, "peak X < 1 mm"], body
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenario", nargs="+", default=["phantom_bus", "paper_bus"])
    parser.add_argument("--duration", type=float, default=20.0, help="s of breathing")
    parser.add_argument("--skip", type=float, default=8.0, help="s left out at the start")
    parser.add_argument("--bus-delay-ms", type=float, default=3.0)
    parser.add_argument("--position-hz", type=float, default=30.0)
    parser.add_argument("--damping", type=float, default=1.4)
    parser.add_argument("--rows", nargs="+", help="row names (default all)")
    parser.add_argument("--markdown", help="also write the tables to FILE")
    args = parser.parse_args()
    out = []
    for name in args.scenario:
        rows = []
        for label, settings in ROWS:
            if args.rows and label not in args.rows:
                continue
            r = run(name, settings, args)
            rms, peak = r["true"]
            print(
                f"{name:12s} {label:24s} X {1e6 * rms[3]:6.0f} / {1e6 * peak[3]:6.0f} um  "
                f"theta {1e6 * rms[1]:6.0f} urad  peak X < 1 mm {r['within']}  {r['wall_s']:.0f} s",
                flush=True,
            )
            rows.append((label, r))
        out += [*lines(name, rows), ""]
    print("\n".join(out))
    if args.markdown:
        Path(args.markdown).write_text("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
