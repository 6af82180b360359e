"""How accurate is the plant: a step-size study of the Drake plant and of the same robot in MuJoCo.

Writes docs/accuracy.md and docs/accuracy.png (never edit them by hand: rerun this) and prints
one line per figure, e.g. ``order drake_sap fall_home position 1.00``. For plant steps of 1, 0.5,
0.2, 0.1 and 0.05 ms, against the same engine at 0.01 ms: platform pose error at 0.05 and 0.1 s
of zero-torque falls and of rises under 1.2 x the holding torques, from home and tilted; relative
energy change; max loop-closure error; wall time per simulated second; the paper manoeuvre in
closed loop on the Drake plant at each step; MuJoCo against Drake; the rods' ball-joint
coordinates against gimbal lock. Runs in one process (about 1-2 min).

Usage: python benchmarks/accuracy.py [--docs docs] [--paper-duration 2] [--quick]
"""

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from stewart_drake.analysis import accuracy as acc
from stewart_drake.base.fileio import atomic_write
from stewart_drake.base.tables import markdown_lines
from stewart_drake.plant import ball_joints
from stewart_drake.references.trajectories import paper_manoeuvre
from stewart_drake.robot import limits
from stewart_drake.robot.geometry import X_HOME, StewartGeometry

AXES_UNITS = (
    ("phi", "mrad"),
    ("theta", "mrad"),
    ("psi", "mrad"),
    ("X", "mm"),
    ("Y", "mm"),
    ("Z", "mm"),
)
#: The default step is the largest one at which the paper manoeuvre, the use this plant is built
#: for, tracks as at the finest step to this fraction of the LQI's error scales (1 mrad | 1 mm,
#: controller.LqiScales) on every axis ...
TRACKING_TOLERANCE = 0.01
#: ... and keeps its loops closed to 1 % of the DivergenceGuard's 1 mm bound.
CLOSURE_LIMIT_M = 1e-5
#: Workspace sample of the ball-joint study (same box as tests/test_accuracy_coordinates.py).
BOX_LO = np.array([-0.75, -0.75, -1.0, -0.10, -0.18, 0.19])
BOX_HI = np.array([0.75, 0.75, 1.0, 0.20, 0.18, 0.42])


def engines() -> list:
    try:
        import mujoco  # noqa: F401
    except ImportError:
        print("mujoco not installed: MuJoCo rows skipped (pip install -e '.[mujoco]')")
        return ["drake_sap"]
    return ["drake_sap", "mujoco_rk4", "mujoco_implicitfast"]


def open_loop_study(names, steps, reference_step):
    """Every engine x scenario x step, with the errors against the engine's own reference."""
    rows, runs = [], {}
    for engine in names:
        for scenario in acc.SCENARIOS:
            ref = acc.simulate(engine, scenario, reference_step)
            runs[engine, scenario.name, reference_step] = ref
            for h in steps:
                run = acc.simulate(engine, scenario, h)
                runs[engine, scenario.name, h] = run
                dp, dR = acc.pose_errors(run.x, ref.x)
                rows.append(
                    {
                        "engine": engine,
                        "scenario": scenario.name,
                        "step_s": h,
                        "position_error_m": dp.tolist(),
                        "rotation_error_rad": dR.tolist(),
                        "energy_change": run.energy_change,
                        "max_closure_m": run.max_closure_m,
                        "wall_per_sim_s": run.wall_s / run.sim_s,
                    }
                )
                print(
                    f"error {engine} {scenario.name} step {1e3 * h:g} ms: position "
                    f"{dp[0]:.3g} {dp[1]:.3g} m, rotation {dR[0]:.3g} {dR[1]:.3g} rad at "
                    f"{acc.SAMPLE_TIMES_S[0]:g} {acc.SAMPLE_TIMES_S[1]:g} s; energy "
                    f"{run.energy_change:+.3g}; closure {run.max_closure_m:.3g} m"
                )
            rows.append(
                {
                    "engine": engine,
                    "scenario": scenario.name,
                    "step_s": reference_step,
                    "reference": True,
                    "energy_change": ref.energy_change,
                    "max_closure_m": ref.max_closure_m,
                    "wall_per_sim_s": ref.wall_s / ref.sim_s,
                }
            )
    return rows, runs


def orders(rows, names, steps):
    """Observed order of every figure that should shrink with the step, per engine x scenario."""
    out = {}
    for engine in names:
        for scenario in acc.SCENARIOS:
            sel = [
                r
                for r in rows
                if r["engine"] == engine
                and r["scenario"] == scenario.name
                and not r.get("reference")
            ]
            h = [r["step_s"] for r in sel]
            figures = {
                "position": [r["position_error_m"][-1] for r in sel],
                "rotation": [r["rotation_error_rad"][-1] for r in sel],
                "energy": [abs(r["energy_change"]) for r in sel],
                "closure": [r["max_closure_m"] for r in sel],
            }
            out[engine, scenario.name] = {k: acc.observed_order(h, v) for k, v in figures.items()}
            print(
                f"order {engine} {scenario.name} "
                + " ".join(f"{k} {v:.2f}" for k, v in out[engine, scenario.name].items())
            )
    return out


def cross_engine(runs, steps, reference_step):
    """Drake vs MuJoCo RK4 at equal steps, raw and with Drake extrapolated to step 0."""
    out = []
    fine, finer = steps[-2], steps[-1]
    for scenario in acc.SCENARIOS:
        key = ("mujoco_rk4", scenario.name)
        if (*key, fine) not in runs:
            return out
        mj = runs[(*key, fine)].x
        drake = runs["drake_sap", scenario.name, fine].x
        extrapolated = 2 * runs["drake_sap", scenario.name, finer].x - drake
        row = {"scenario": scenario.name, "step_s": fine}
        for label, x in (
            ("equal_step", drake),
            ("extrapolated", extrapolated),
            ("references", None),
        ):
            if x is None:
                x, mj_x = (
                    runs["drake_sap", scenario.name, reference_step].x,
                    runs[(*key, reference_step)].x,
                )
            else:
                mj_x = mj
            dp, dR = acc.pose_errors(mj_x, x)
            row[label] = {"position_m": dp.tolist(), "rotation_rad": dR.tolist()}
        out.append(row)
        print(
            f"drake_vs_mujoco {scenario.name} at {1e3 * fine:g} ms: "
            f"{row['equal_step']['position_m'][-1]:.3g} m, Drake extrapolated "
            f"{row['extrapolated']['position_m'][-1]:.3g} m, references "
            f"{row['references']['position_m'][-1]:.3g} m at 0.1 s"
        )
    return out


def holds(names):
    """Drift over 1 s at 1 ms under the virtual-work torques, home and tilted, each engine."""
    out = []
    for engine in [n for n in names if n != "mujoco_implicitfast"]:
        for label, x0 in (("home", X_HOME), ("tilted", acc.X_TILTED)):
            run = acc.simulate(
                engine,
                acc.OpenLoopCase("hold", tuple(x0), 1.0),
                1e-3,
                sample_times=(0.25, 0.5, 0.75, 1.0),
            )
            drift = np.abs(run.x - x0)
            row = {
                "engine": engine,
                "pose": label,
                "position_m": float(drift[:, 3:].max()),
                "rotation_rad": float(drift[:, :3].max()),
                "closure_m": run.max_closure_m,
            }
            out.append(row)
            print(
                f"hold_drift_1s {engine} {label}: {row['position_m']:.2g} m, "
                f"{row['rotation_rad']:.2g} rad, closure {row['closure_m']:.2g} m"
            )
    return out


def paper_study(steps, duration_s):
    out = []
    for h in steps:
        r = acc.paper_run(h, duration_s)
        out.append(
            {
                "step_s": h,
                "rms_error": r["rms_error"].tolist(),
                **{k: v for k, v in r.items() if k != "rms_error"},
            }
        )
        print(
            f"paper {1e3 * h:g} ms: RMS phi {1e3 * r['rms_error'][0]:.4g} mrad, Z "
            f"{1e3 * r['rms_error'][5]:.4g} mm; closure {r['max_closure_m']:.3g} m; "
            f"{r['wall_per_sim_s']:.3g} s wall per sim s; rod |pitch| "
            f"{np.rad2deg(r['max_pitch_rad']):.1f} deg"
        )
    return out


def _smallest_rotation_frames(R_WF: np.ndarray) -> np.ndarray:
    """Frames with the same z, turned from the world by the smallest rotation (the obvious choice,
    for comparison with the SDF's)."""
    from scipy.spatial.transform import Rotation

    z = R_WF[:, :, 2]
    axis = np.cross([0.0, 0.0, 1.0], z)
    angle = np.arcsin(np.linalg.norm(axis, axis=1))
    rotvec = axis / np.linalg.norm(axis, axis=1, keepdims=True) * angle[:, None]
    return Rotation.from_rotvec(rotvec).as_matrix()


def coordinate_study(geometry, n_samples, paper_duration_s):
    x = np.random.default_rng(0).uniform(BOX_LO, BOX_HI, (n_samples, 6))
    inside = x[limits.is_reachable(geometry, x).reachable]
    paper = paper_manoeuvre().evaluate(np.arange(0.0, 10.0, 1e-2))[0]
    frames = {
        "plant": None,
        "smallest_rotation": _smallest_rotation_frames(
            ball_joints.joint_frames_at_home(geometry)[1]
        ),
    }
    box = (
        f"roll and pitch +-{np.rad2deg(BOX_HI[0]):.0f}, yaw +-{np.rad2deg(BOX_HI[2]):.0f} deg, "
        f"X {BOX_LO[3]:g}..{BOX_HI[3]:g}, Y {BOX_LO[4]:g}..{BOX_HI[4]:g}, "
        f"Z {BOX_LO[5]:g}..{BOX_HI[5]:g} m"
    )
    out = {
        "n_samples": n_samples,
        "n_inside": len(inside),
        "box": box,
        "cone_deg": geometry.crank_joint_cone_deg,
        "max_turn_deg": np.rad2deg(
            ball_joints.rod_turn_from_home(geometry, inside).max(axis=0)
        ).tolist(),
        "paper_max_turn_deg": float(
            np.rad2deg(ball_joints.rod_turn_from_home(geometry, paper).max())
        ),
    }
    for name, R in frames.items():
        pitch = np.abs(ball_joints.rod_ball_rpy(geometry, inside, R_WF_home=R)[..., 1])
        paper_pitch = np.abs(ball_joints.rod_ball_rpy(geometry, paper, R_WF_home=R)[..., 1])
        out[name] = {
            "singular_misalignment_deg": np.rad2deg(
                ball_joints.singular_direction_misalignment(geometry, R)
            ).tolist(),
            "max_pitch_deg": np.rad2deg(pitch.max(axis=0)).tolist(),
            "share_above_60_deg": float(np.mean(pitch.max(axis=-1) > np.deg2rad(60))),
            "paper_max_pitch_deg": float(np.rad2deg(paper_pitch.max())),
        }
        print(
            f"ball_joint_pitch {name} frames: singular directions "
            f"{min(out[name]['singular_misalignment_deg']):.1f} deg out of the crank plane at "
            f"least (cone {geometry.crank_joint_cone_deg:g}); max |pitch| "
            f"{max(out[name]['max_pitch_deg']):.1f} deg over {len(inside)} poses inside the "
            f"limits, {out[name]['paper_max_pitch_deg']:.1f} along the paper manoeuvre"
        )
    out["pitch_bound_deg"] = np.rad2deg(ball_joints.pitch_bound(geometry)).tolist()
    run = acc.paper_run(1e-3, paper_duration_s)
    out["paper_run"] = {
        "duration_s": paper_duration_s,
        "max_pitch_deg": float(np.rad2deg(run["max_pitch_rad"])),
        "max_pitch_no_spin_deg": float(np.rad2deg(run["max_pitch_no_spin_rad"])),
    }
    print(
        f"ball_joint_pitch simulated paper run ({paper_duration_s:g} s, 1 ms): max |pitch| "
        f"{out['paper_run']['max_pitch_deg']:.1f} deg from the states, "
        f"{out['paper_run']['max_pitch_no_spin_deg']:.1f} deg without spin"
    )
    return out


def default_step(paper):
    """The largest step meeting TRACKING_TOLERANCE and CLOSURE_LIMIT_M (see their comments)."""
    from stewart_drake.control.lqi.driver import LqiScales

    finest = min(paper, key=lambda r: r["step_s"])
    best, scale = np.asarray(finest["rms_error"]), np.asarray(LqiScales().pose)
    ok = [
        r
        for r in paper
        if np.all(np.abs(np.asarray(r["rms_error"]) - best) <= TRACKING_TOLERANCE * scale)
        and r["max_closure_m"] < CLOSURE_LIMIT_M
    ]
    return max(ok, key=lambda r: r["step_s"]) if ok else finest


def best_wall(data, engine: str, step_s: float) -> float:
    """Wall s per simulated s of ``engine`` at ``step_s``: the fastest of the four scenario runs,
    the least disturbed by the machine's other load."""
    return float(
        min(
            r["wall_per_sim_s"]
            for r in data["open_loop"]
            if r["engine"] == engine and r["step_s"] == step_s
        )
    )


#: The columns of the per-engine tables of :func:`render`.
OPEN_LOOP_COLUMNS = (
    "scenario",
    "step [ms]",
    "position 0.05 s [m]",
    "position 0.1 s [m]",
    "rotation 0.05 s [rad]",
    "rotation 0.1 s [rad]",
    "energy change",
    "max closure [m]",
    "wall per sim s [s]",
)


def _g(v, digits=2) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{v:.{digits}g}"


def render(data) -> str:
    steps, ref = data["steps_s"], data["reference_step_s"]
    ms = lambda h: f"{1e3 * h:g}"  # noqa: E731
    names = data["engines"]
    L = [
        "# How accurate is the plant",
        "",
        f"Generated by `python benchmarks/accuracy.py` ({data['wall_s']:.0f} s wall in one "
        f"process; Drake {data['versions']['drake']}, MuJoCo {data['versions']['mujoco']}, "
        f"Python {data['versions']['python']}"
        f"{'; QUICK mode: smoke-test settings, not figures to quote' if data['quick'] else ''})."
        " Do not edit by hand: rerun the benchmark.",
        "",
        "What is measured. Four open-loop scenarios start at rest, assembled, under constant "
        "motor torques: a zero-torque **fall** and a **rise** under 1.2 x the virtual-work "
        "holding torques (`statics.holding_torques`), each from **home** and from a **tilted** "
        "pose (roll 8.6, pitch -5.7, yaw 5.7 deg, X 20 mm, Y -10 mm, Z 0.29 m). Each runs 0.1 s "
        f"at plant steps {', '.join(ms(h) for h in steps)} ms and at {ms(ref)} ms, the "
        "reference, on the same engine. Pose error: distance between platform positions and "
        "angle of the relative rotation at 0.05 and 0.1 s. Energy change: (E(0.1 s) - E(0)) / "
        "KE(0.1 s), E = kinetic + potential (Drake `CalcKineticEnergy` / "
        "`CalcPotentialEnergy`, MuJoCo `mjData.energy`) minus the work of the torques "
        "sum_i T_i (theta_i(t) - theta_i(0)): the share of the kinetic energy the integrator "
        "lost (< 0) or made up. Closure: largest distance between a rod's top and its platform "
        "joint, checked every 1 ms. Wall time: stepping only, per simulated second, this "
        "machine (2 cores, one used; the other was busy, so treat speeds as +-30 %).",
        "",
        "Engines: `drake_sap`, the package's plant (discrete SAP, ball constraints, gravity "
        "9.81); `mujoco_rk4` and `mujoco_implicitfast`, the MJCF of "
        "`stewart-drake mjcf --scenario paper_ideal` "
        "(`stewart_drake/plant/mjcf.py`; same bodies, frames and inertias, loops closed by "
        "`connect` equalities whose time constant MuJoCo sets to 2 x step) with MuJoCo's RK4 "
        "(the MJCF default) and its implicit-in-velocity Euler.",
        "",
    ]

    # Default step first: what a user came for.
    chosen, paper = data["default_step"], data["paper"]
    fall = {
        r["step_s"]: r
        for r in data["open_loop"]
        if r["engine"] == "drake_sap" and r["scenario"] == "fall_home" and not r.get("reference")
    }
    f1 = fall[chosen["step_s"]]
    fine = min(fall)
    cost_ratio = best_wall(data, "drake_sap", fine) / best_wall(data, "drake_sap", chosen["step_s"])
    tracking_change = max(
        np.abs(np.subtract(r["rms_error"], paper[-1]["rms_error"])).max() for r in paper
    )
    rk4 = [
        r
        for r in data["open_loop"]
        if r["engine"] == "mujoco_rk4"
        and r["scenario"] == "fall_home"
        and r["step_s"] == chosen["step_s"]
    ]
    rk4_error = rk4[0]["position_error_m"][-1] if rk4 else None
    rk4_text = (
        f" MuJoCo RK4 at {ms(chosen['step_s'])} ms: "
        f"{1e3 * rk4[0]['position_error_m'][-1]:.2g} mm, "
        f"{100 * rk4[0]['energy_change']:+.2g} %, {rk4[0]['max_closure_m']:.2g} m, at "
        f"{best_wall(data, 'mujoco_rk4', chosen['step_s']):.2g} s wall per simulated s."
        if rk4
        else ""
    )
    L += [
        "## The default step",
        "",
        f"**{ms(chosen['step_s'])} ms**: the largest step at which the paper manoeuvre "
        f"(closed loop, LQI at 1 kHz, {data['paper_duration_s']:g} s) tracks as at the finest "
        f"step to {100 * TRACKING_TOLERANCE:g} % of the LQI's error scales (1 mrad | 1 mm) on "
        f"every axis and keeps its loops closed below {CLOSURE_LIMIT_M:g} m (1 % of the "
        f"guard's 1 mm); with the controller at 1 kHz it is also the largest step allowed "
        f"(the control period must be a whole multiple of it). There the loops stay closed to "
        f"{chosen['max_closure_m']:.2g} m and the run costs "
        f"{chosen['wall_per_sim_s']:.2g} s wall per simulated s against "
        f"{paper[-1]['wall_per_sim_s']:.2g} at {ms(paper[-1]['step_s'])} ms, and its RMS "
        f"tracking errors, all below {1e3 * max(max(r['rms_error']) for r in paper):.2g} "
        f"mrad | mm, move by at most {1e3 * tracking_change:.2g} mrad | mm from the finest "
        f"step's (table below). Open loop, SAP is first order (orders below): a free fall "
        f"from home (the platform drops {1e3 * data['fall_distance_m']:.0f} mm in 0.1 s) is "
        f"{1e3 * f1['position_error_m'][-1]:.2g} mm off after 0.1 s, loses "
        f"{-100 * f1['energy_change']:.2g} % of its kinetic energy and opens the loops by "
        f"{f1['max_closure_m']:.2g} m. Where that matters (fast unactuated motion), "
        f"{ms(fine)} ms brings it to {1e3 * fall[fine]['position_error_m'][-1]:.2g} mm, "
        f"{-100 * fall[fine]['energy_change']:.2g} % and {fall[fine]['max_closure_m']:.2g} m "
        f"for {cost_ratio:.2g} x the wall time.{rk4_text}",
        "",
    ]

    # Orders.
    L += [
        "## Observed order of convergence",
        "",
        "Least-squares slope of log(error at 0.1 s) against log(step) over the five steps "
        "(`numpy.polyfit`; errors below 1e-13, round-off, left out; — where fewer than three "
        "remain). The reference's own error biases the finest point a little (SAP's "
        "0.01 ms error is a fifth of its 0.05 ms one), which lifts first-order slopes a "
        "little above 1. Mean over the four scenarios:",
        "",
    ]
    mean = {}
    for key, o in data["orders"].items():
        for k, v in o.items():
            mean.setdefault((key.split("/")[0], k), []).append(v)
    L += [
        f"- `{engine}`: "
        + ", ".join(
            f"{k} {_g(float(np.nanmean(mean[engine, k])), 3)}"
            for k in ("position", "rotation", "energy", "closure")
            if np.isfinite(mean[engine, k]).any()
        )
        for engine in names
    ]
    L += [
        "",
        "Pose and energy errors of SAP and of MuJoCo's implicitfast are first order, their "
        "loop-closure errors second order. MuJoCo's RK4 is second order rather than fourth "
        "because its loop constraints' time constant follows the step (2 x step), so the "
        "model itself changes with the step"
        + (
            f"; its fall from home still ends {_g(f1['position_error_m'][-1] / rk4_error)} "
            f"times closer to its reference than SAP's at {ms(chosen['step_s'])} ms."
            if rk4
            else "."
        ),
        "",
    ]
    orders = ("position", "rotation", "energy", "closure")
    rows = [[*key.split("/"), *(_g(o[k], 3) for k in orders)] for key, o in data["orders"].items()]
    L += markdown_lines(["engine", "scenario", *orders], rows) + [""]

    # Per-engine tables.
    for engine in names:
        rows = []
        for r in data["open_loop"]:
            if r["engine"] != engine:
                continue
            tail = [f"{r['energy_change']:+.2g}", _g(r["max_closure_m"]), _g(r["wall_per_sim_s"])]
            if r.get("reference"):
                rows.append([r["scenario"], f"{ms(r['step_s'])} (ref)", *[None] * 4, *tail])
                continue
            dp, dR = r["position_error_m"], r["rotation_error_rad"]
            rows.append([r["scenario"], ms(r["step_s"]), *map(_g, (*dp[:2], *dR[:2])), *tail])
        L += [f"### {engine}: errors against itself at {ms(ref)} ms", ""]
        L += markdown_lines(OPEN_LOOP_COLUMNS, rows) + [""]

    # Cost.
    L += [
        "## Wall time per simulated second",
        "",
        "Open loop: the fastest of the four scenario runs (stepping only; the least disturbed "
        "by the machine's other load). Closed loop: the paper "
        "manoeuvre's whole Diagram (plant, LQI at 1 kHz re-scheduled every 10 ms, reference "
        "sources, loggers, the DivergenceGuard checking every 10 ms).",
        "",
    ]
    rows = []
    for h in [*steps, ref]:
        cells = [_g(best_wall(data, engine, h)) for engine in names]
        p = [r for r in paper if r["step_s"] == h]
        cells.append(_g(p[0]["wall_per_sim_s"]) if p else "")
        rows.append([ms(h), *cells])
    L += markdown_lines(["step [ms]", *names, "paper run, Drake closed loop"], rows) + [""]

    # Paper manoeuvre.
    L += [
        f"## The paper manoeuvre in closed loop ({data['paper_duration_s']:g} s, Drake)",
        "",
        "RMS tracking error over the second half (true pose from the plant state), max "
        "loop-closure error, and the largest |pitch| of the rods' `BallRpyJoint`s read from "
        "the logged states. Control period 1 ms at every plant step.",
        "",
    ]
    header = ["step [ms]", *(f"{a} [{u}]" for a, u in AXES_UNITS), "max closure [m]"]
    header += ["wall per sim s", "rod max pitch [deg]"]
    rows = [
        [ms(r["step_s"]), *(_g(1e3 * v, 4) for v in r["rms_error"]), _g(r["max_closure_m"])]
        + [_g(r["wall_per_sim_s"]), f"{np.rad2deg(r['max_pitch_rad']):.1f}"]
        for r in paper
    ]
    L += markdown_lines(header, rows) + [""]

    # MuJoCo vs Drake.
    if data["cross_engine"]:
        h = data["cross_engine"][0]["step_s"]
        L += [
            "## The same robot in MuJoCo",
            "",
            f"Platform position and rotation, MuJoCo RK4 against Drake, at 0.05 / 0.1 s. "
            f"*Equal step*: both at {ms(h)} ms. *Drake extrapolated*: Drake's {ms(h)} and "
            f"{ms(steps[-1])} ms runs extrapolated to step 0 (2 x(h/2) - x(h), SAP being first "
            f"order) against MuJoCo at {ms(h)} ms. *References*: both at {ms(ref)} ms. The "
            "gap at equal step is SAP's first-order error; with it extrapolated away the two "
            "engines agree to about 1e-8 m and 1e-7 rad (what is left of the second-order "
            "terms): they simulate the same robot.",
            "",
        ]
        rows = []
        for r in data["cross_engine"]:
            cells = []
            for label in ("equal_step", "extrapolated", "references"):
                cells += [
                    " / ".join(_g(v) for v in r[label]["position_m"]),
                    " / ".join(_g(v) for v in r[label]["rotation_rad"]),
                ]
            rows.append([r["scenario"], *cells])
        header = ["scenario", "equal step [m]", "equal step [rad]", "Drake extrapolated [m]"]
        header += ["Drake extrapolated [rad]", "references [m]", "references [rad]"]
        L += markdown_lines(header, rows)
        L += [
            "",
            "Holding a pose for 1 s at 1 ms under the virtual-work torques (largest drift "
            "over the second; the tests bound these). Constant torques make the pose an "
            "unstable equilibrium (fastest mode e^(9.9 t) from the linearized statics), so the "
            "drift is each engine's first numerical error grown about 2e4 times; SAP's "
            "numerical damping slows that growth, RK4 follows it.",
            "",
        ]
        header = ["engine", "pose", "position drift [m]", "rotation drift [rad]"]
        rows = [
            [r["engine"], r["pose"], _g(r["position_m"]), _g(r["rotation_rad"]), _g(r["closure_m"])]
            for r in data["holds"]
        ]
        L += markdown_lines(header + ["max closure [m]"], rows) + [""]

    # Coordinates.
    c = data["coordinates"]
    plant, old = c["plant"], c["smallest_rotation"]
    L += [
        "## The rods' ball-joint coordinates and gimbal lock",
        "",
        "Drake parses each rod's ball joint into a `BallRpyJoint` (R_FM = Rz Ry Rx), singular at "
        "pitch = +-90 deg: for a rod turned from its home frame F by the smallest rotation (what "
        "`closed_chain.assemble` writes; no spin) pitch = asin(e . x_F), e the rod direction, so "
        "gimbal lock needs the rod along +-x_F. Those two singular directions are fixed in the "
        "crank; the rod end's cone (`crank_joint_cone_deg`) bounds how far a rod leaves the "
        "crank's plane, asin|e . u_i|. `stewart_drake/plant/ball_joints.py` computes the rpy "
        "(checked against `BallRpyJoint.get_angles`).",
        "",
        f"- **The SDF's frames** (x_F along the part of the bolt axis u_i normal to the home "
        f"rod): the singular directions lie "
        f"{min(plant['singular_misalignment_deg']):.1f} deg out of the crank's plane for every "
        f"leg, outside the {c['cone_deg']:g} deg cone, so inside the limits |pitch| <= "
        f"{max(c['pitch_bound_deg']):.1f} deg whatever the pose. Measured over {c['n_inside']} "
        f"poses inside every limit (`limits.is_reachable`; {c['n_samples']} uniform draws "
        f"in {c['box']}): max "
        f"|pitch| {max(plant['max_pitch_deg']):.1f} deg; along the paper manoeuvre "
        f"{plant['paper_max_pitch_deg']:.1f} deg. The test "
        "(`tests/test_accuracy_coordinates.py`) asserts < 45 deg.",
        f"- **Frames turned from the world by the smallest rotation** (the obvious choice, shown "
        f"for comparison): singular directions "
        f"{min(old['singular_misalignment_deg']):.1f} deg out "
        f"of the plane for legs 2-5, *inside* the cone; max |pitch| "
        f"{max(old['max_pitch_deg']):.1f} deg over the same poses "
        f"({100 * old['share_above_60_deg']:.1f} % of them above 60 deg), "
        f"{old['paper_max_pitch_deg']:.1f} deg along the paper manoeuvre. The rod is "
        "axisymmetric, so the change of frames changed coordinates, not dynamics.",
        f"- **Spin.** Nothing holds a rod's spin about its own axis, and a simulated rod does "
        f"spin, which moves its rpy off the no-spin values. Whatever the spin, |pitch| is at "
        f"most the rod's turn from its home direction seen from its crank: "
        f"{c['paper_max_turn_deg']:.1f} deg along the paper manoeuvre (so that run cannot "
        f"reach gimbal lock at any spin), but up to {max(c['max_turn_deg']):.1f} deg at the "
        f"far edge of the workspace, where a rod that had spun far enough could reach it in "
        f"principle. Read from the states of a "
        f"{c['paper_run']['duration_s']:g} s paper run at 1 ms, max |pitch| is "
        f"{c['paper_run']['max_pitch_deg']:.1f} deg "
        f"({c['paper_run']['max_pitch_no_spin_deg']:.1f} deg for the same poses without "
        f"spin). MuJoCo's "
        "ball joints are quaternions and have no such singularity.",
        "",
        "![accuracy](accuracy.png)",
        "",
    ]
    return "\n".join(L)


def plot(data, path: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    styles = {"fall_home": "-o", "fall_tilted": "--s", "rise_home": ":^", "rise_tilted": "-.v"}
    colors = {"drake_sap": "C0", "mujoco_rk4": "C3", "mujoco_implicitfast": "C2"}
    panels = [
        ("position error at 0.1 s [m]", lambda r: r["position_error_m"][-1]),
        ("|energy change| / KE at 0.1 s", lambda r: abs(r["energy_change"])),
        ("max loop-closure error [m]", lambda r: r["max_closure_m"]),
    ]

    for ax, (label, value) in zip(axes.flat, panels):
        for engine in data["engines"]:
            hollow = {"mfc": "none"} if engine == "mujoco_implicitfast" else {}
            for scenario, style in styles.items():
                sel = [
                    r
                    for r in data["open_loop"]
                    if r["engine"] == engine
                    and r["scenario"] == scenario
                    and not r.get("reference")
                ]
                h = np.array([r["step_s"] for r in sel]) * 1e3
                y = np.array([value(r) for r in sel])
                # Drake's lines wide and pale beneath, so that where MuJoCo implicitfast's
                # coincide with them (SAP and implicitfast are both first order) both show.
                wide = (
                    {"lw": 4, "ms": 8, "alpha": 0.45, "zorder": 1} if engine == "drake_sap" else {}
                )
                ax.loglog(
                    h,
                    np.where(y > 0, y, np.nan),
                    style,
                    color=colors[engine],
                    **({"ms": 5, "lw": 1, "zorder": 2} | wide | hollow),
                )
        ax.set_xlabel("plant step [ms]")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which="both")
    h = np.array(data["steps_s"]) * 1e3
    y0 = [
        r["position_error_m"][-1]
        for r in data["open_loop"]
        if r["engine"] == "drake_sap"
        and r["scenario"] == "fall_home"
        and r["step_s"] == data["steps_s"][0]
    ][0]
    axes[0, 0].loglog(h, y0 * 2 * h / h[0], "k:", lw=1)
    axes[0, 0].legend(
        [
            Line2D(
                [],
                [],
                color=colors[e],
                marker="o",
                mfc="none" if e == "mujoco_implicitfast" else colors[e],
                **({"lw": 4, "ms": 8, "alpha": 0.45} if e == "drake_sap" else {}),
            )
            for e in data["engines"]
        ]
        + [Line2D([], [], color="k", ls=":")],
        [f"{e} (wide, beneath)" if e == "drake_sap" else e for e in data["engines"]] + ["order 1"],
        fontsize=7,
    )
    axes[1, 0].legend(
        [Line2D([], [], color="gray", ls=st[:-1], marker=st[-1]) for st in styles.values()],
        list(styles),
        fontsize=7,
    )
    ax = axes[1, 1]
    for engine in data["engines"]:
        ax.loglog(
            h,
            [best_wall(data, engine, step) for step in data["steps_s"]],
            "-o",
            color=colors[engine],
            ms=5,
            lw=1.5,
            label=f"{engine}, open loop",
            **({"mfc": "none"} if engine == "mujoco_implicitfast" else {}),
        )
    ax.set_xlabel("plant step [ms]")
    ax.set_ylabel("wall s per simulated s (fastest run)")
    ax.grid(alpha=0.3, which="both")
    paper = data["paper"]
    axes[1, 1].loglog(
        [1e3 * r["step_s"] for r in paper],
        [r["wall_per_sim_s"] for r in paper],
        "k-D",
        ms=4,
        lw=1.5,
        label="paper run, Drake closed loop",
    )
    axes[1, 1].legend(fontsize=7)
    fig.suptitle(
        f"Step-size study: each engine against itself at {1e3 * data['reference_step_s']:g} ms"
    )
    fig.tight_layout()
    atomic_write(path, lambda f: fig.savefig(f, dpi=100, format="png"))
    plt.close(fig)


def versions() -> dict:
    import pydrake

    try:
        import mujoco

        mj = mujoco.__version__
    except ImportError:
        mj = "not installed"
    drake = getattr(pydrake, "__version__", None)
    if drake is None:
        from importlib.metadata import version

        drake = version("drake")
    return {"drake": drake, "mujoco": mj, "python": platform.python_version()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--docs", default="docs", help="folder of accuracy.md and .png (docs)")
    parser.add_argument(
        "--paper-duration",
        type=float,
        default=2.0,
        help="simulated s of each closed-loop paper run (2)",
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="steps 1, 0.5, 0.2 ms against 0.1 ms, 0.2 s paper runs: a smoke "
        "test of the pipeline, not figures to quote",
    )
    parser.add_argument(
        "--json",
        default="results/accuracy/accuracy.json",
        help="every figure as JSON (results/accuracy/accuracy.json)",
    )
    args = parser.parse_args(argv)
    steps = acc.STEPS_S[:3] if args.quick else acc.STEPS_S
    reference = 1e-4 if args.quick else acc.REFERENCE_STEP_S
    paper_duration = 0.2 if args.quick else args.paper_duration
    geometry = StewartGeometry()
    names = engines()
    wall0 = time.perf_counter()
    rows, runs = open_loop_study(names, steps, reference)
    data = {
        "steps_s": list(steps),
        "reference_step_s": reference,
        "engines": names,
        "quick": args.quick,
        "paper_duration_s": paper_duration,
        "open_loop": rows,
        "orders": {f"{e}/{s}": o for (e, s), o in orders(rows, names, steps).items()},
        "cross_engine": cross_engine(runs, steps, reference),
        "holds": holds(names),
        "paper": paper_study(steps, paper_duration),
        "coordinates": coordinate_study(
            geometry, 40_000 if args.quick else 400_000, paper_duration if args.quick else 10.0
        ),
        "versions": versions(),
    }
    data["default_step"] = default_step(data["paper"])
    data["fall_distance_m"] = float(X_HOME[5] - runs["drake_sap", "fall_home", reference].x[-1, 5])
    print(f"default_step {1e3 * data['default_step']['step_s']:g} ms")
    data["wall_s"] = time.perf_counter() - wall0
    docs = Path(args.docs)
    atomic_write(docs / "accuracy.md", lambda f: f.write(render(data).encode()))
    plot(data, docs / "accuracy.png")
    atomic_write(Path(args.json), lambda f: f.write(json.dumps(data, indent=1).encode()))
    print(
        f"wrote {docs / 'accuracy.md'}, {docs / 'accuracy.png'} and {args.json} "
        f"({data['wall_s']:.0f} s)"
    )


if __name__ == "__main__":
    main()
