"""Learn the feed-forward model a run may start from instead of zero, on the library's motions that
do not repeat per breath, and write it to stewart_drake/data/feedforward_library.npz (numbers
only, :func:`stewart_drake.control.feedforward_basis.save_learned`).

    python tools/feedforward_library_model.py [--duration 120]

Each motion runs ``--duration`` s on ``phantom_hardware`` (``reproduce``'s scenario) with
``learning: !FeedforwardTuning``, the first from zero and each next one from the model the
previous one ended with: breathing at 4.2 s with a 72 bpm heartbeat not locked to it, then
irregular breathing (seed 3). About four CPU-minutes.
"""

import argparse

from stewart_drake.control.feedforward_basis import LIBRARY_MODEL, save_learned
from stewart_drake.control.feedforward_tuning import FeedforwardTuning
from stewart_drake.organ_motion import SCENARIO
from stewart_drake.organ_motion.reproduction import run
from stewart_drake.references.organ.library import make_motion
from stewart_drake.run.scenario_io import load_scenario

#: The motions learned from, in order: (name, parameters).
MOTIONS = (("breathing_heartbeat", {"period": "4.2s"}), ("irregular_breathing", {"seed": "3"}))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=120.0, help="s per motion")
    args = parser.parse_args()
    model = ""
    for name, parameters in MOTIONS:
        scenario = load_scenario(SCENARIO)
        scenario.duration_s = args.duration
        scenario.learning = FeedforwardTuning(learned_from=model)
        _, log, _, learned = run(scenario, make_motion(name, parameters))
        model = str(save_learned(LIBRARY_MODEL, learned, SCENARIO))
        print(f"{name}: learned over {args.duration:g} s, written to {model}")


if __name__ == "__main__":
    main()
