"""Workspace benchmark: poses classified per second (reachable + cond(J) + holding torques).

Prints one line per figure. Target: 1e5 poses in < 10 s on a 2-core machine.
Run: python benchmarks/workspace.py
"""

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # measure this checkout
from stewart_drake.analysis import workspace
from stewart_drake.robot import forward_kinematics, kinematics
from stewart_drake.robot.geometry import X_HOME, StewartGeometry


def main(n: int = 100_000) -> None:
    geometry = StewartGeometry()
    rng = np.random.default_rng(0)
    x = X_HOME + rng.uniform(-1, 1, (n, 6)) * [0.5, 0.5, 0.8, 0.15, 0.15, 0.12]
    workspace.classify(geometry, x[:1000])  # warm up
    t0 = time.perf_counter()
    c = workspace.classify(geometry, x)
    serial = time.perf_counter() - t0
    print(f"poses_per_s {n / serial:.0f} ({n} poses / {serial:.2f} s, one process)")
    t0 = time.perf_counter()
    workspace.sweep(geometry, x, jobs=2, chunk=25_000)
    parallel = time.perf_counter() - t0
    print(f"poses_per_s_2_jobs {n / parallel:.0f} ({n} poses / {parallel:.2f} s, incl. spawn)")
    print(f"reachable_fraction {c['reachable'].mean():.3f} (of {n} random poses)")

    ok = x[c["usable"]][:10_000]
    theta = kinematics.ik(geometry, ok)
    t0 = time.perf_counter()
    x_fk, converged, iterations, _ = forward_kinematics.fk_unchecked(geometry, theta)
    dt = time.perf_counter() - t0
    print(f"fk_per_s {len(ok) / dt:.0f} ({len(ok)} poses / {dt:.3f} s, batched Newton from home)")
    print(
        f"fk_round_trip_max_error {np.abs(x_fk - ok)[converged].max():.2e} "
        f"(converged {converged.mean():.4f}, max {iterations.max()} iterations)"
    )

    t0 = time.perf_counter()
    s = workspace.workspace_summary(geometry, resolution=41, jobs=1)
    dt = time.perf_counter() - t0
    ext = s["extent_xyz_m"]
    print(f"workspace_summary_s {dt:.2f} (resolution 41: {2 * 41**3 + 41 * 41 * 24} poses)")
    print(
        f"reachable_volume_m3 {s['volume_m3']:.5f} (usable, cond <= 200: "
        f"{s['usable_volume_m3']:.5f})"
    )
    print("extent_m " + " ".join(f"{a} [{lo:+.4f}, {hi:+.4f}]" for a, (lo, hi) in zip("XYZ", ext)))
    print(
        "extent_rpy_deg "
        + " ".join(
            f"{a} [{np.rad2deg(lo):+.1f}, {np.rad2deg(hi):+.1f}]"
            for a, (lo, hi) in zip(("phi", "theta", "psi"), s["extent_rpy_rad"])
        )
    )
    i = int(np.argmin(np.abs(s["heights"] - X_HOME[5])))
    print(
        f"max_tilt_every_direction_deg {np.rad2deg(s['tilt_every_rad'][i]):.1f} "
        f"(at Z = {s['heights'][i]:.3f} m)"
    )
    print(f"max_holding_torque_Nm {s['max_holding_torque_Nm']:.3f} (over the reachable box)")


if __name__ == "__main__":
    main()
