"""CPU time of the check of a reference before a run, compiled and in its numpy form.

    python benchmarks/reference_check.py                 # breathing 60 s, paper 10 s
    python benchmarks/reference_check.py --repeats 5 --breathing 64

``run.plan.check_reference`` on paper_hardware (every millisecond: the limits, both
singularity measures, the clearance between parts and the motors' torque and speed), over
``breathing_heartbeat`` (``stewart-drake reproduce``'s library motion) and the paper manoeuvre.
Printed per reference and form: the CPU time of this thread (``time.thread_time``; the best of
``--repeats``, after a first call that compiles or loads the kernels), and where the compiled
check's time goes (cProfile's largest own times).
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import pstats
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # measure this checkout

from stewart_drake.references.organ.library import OrganMotionReference  # noqa: E402
from stewart_drake.run import plan as run_plan  # noqa: E402
from stewart_drake.run.plan import make_plan  # noqa: E402
from stewart_drake.run.scenario_io import load_scenario  # noqa: E402


def reference_plan(name: str, duration_s: float):
    """The paper_hardware plan of ``name`` ("breathing" or "paper") for ``duration_s``."""
    scenario = load_scenario("paper_hardware", [f"duration_s={duration_s:g}"])
    if name == "breathing":
        scenario.reference = OrganMotionReference(motion="breathing_heartbeat")
        scenario.validate()
    return make_plan(scenario)


def check(plan, compiled: bool):
    """``check_reference`` of ``plan`` (its series dropped), its validator compiled or in its
    numpy form (``validate_trajectory(compiled=...)``, swapped in for this call)."""
    checked = run_plan.validate_trajectory
    run_plan.validate_trajectory = functools.partial(checked, compiled=compiled)
    try:
        return run_plan.check_reference(plan, keep_series=False)
    finally:
        run_plan.validate_trajectory = checked


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--breathing", type=float, default=60.0, help="breathing's s (60)")
    parser.add_argument("--paper", type=float, default=10.0, help="the manoeuvre's s (10)")
    parser.add_argument("--repeats", type=int, default=3, help="calls per form, best kept (3)")
    parser.add_argument("--top", type=int, default=8, help="profile rows printed (8)")
    args = parser.parse_args()
    for name, duration in (("breathing", args.breathing), ("paper", args.paper)):
        plan = reference_plan(name, duration)
        best = {}
        for compiled in (False, True):
            check(plan, compiled)  # compiles or loads the kernels; warms the clearance model
            times = []
            for _ in range(args.repeats):
                start = time.thread_time()
                check(plan, compiled)
                times.append(time.thread_time() - start)
            best[compiled] = min(times)
        print(
            f"{name} {duration:g} s: numpy {best[False]:.3f} s, compiled {best[True]:.3f} s "
            f"CPU ({best[True] / best[False]:.0%})"
        )
        profile = cProfile.Profile()
        profile.runcall(functools.partial(check, plan, True))
        pstats.Stats(profile).sort_stats("tottime").print_stats(args.top)


if __name__ == "__main__":
    main()
