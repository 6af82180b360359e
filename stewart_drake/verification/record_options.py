"""What a QA record of ``stewart-drake verify`` says of its run, from the command line: the
phantom it names and the reference as the user chose it
(:mod:`~stewart_drake.verification.qa_record` writes them; :mod:`.command` passes
them)."""

from __future__ import annotations


def phantom_words(args, measured) -> str:
    """The phantom a record names: for the robot's encoder log the robot that wrote it (its
    ``--scenario``, whose forward kinematics read it); for a tracker's file the ``--scenario``
    given, or "" when the default stands (it names no phantom: ``--phantom-serial`` does).
    ``measured``: the :class:`~stewart_drake.verification.measured_motion.MeasuredMotion`."""
    from ..organ_motion import SCENARIO

    if measured.from_the_robot:
        return f"{args.scenario} (the robot whose encoder log this is: --scenario)"
    return "" if str(args.scenario) == SCENARIO else str(args.scenario)


def reference_words(args) -> str:
    """The reference a verdict judges against, as the command line chose it: the motion (or
    trace file) with every ``--param``, ``--add`` and trace option given, e.g. ``breathing
    --param tilt=2deg``; the defaults stand for the rest."""
    import argparse

    from ..execution.trace_options import add_trace_arguments

    words = [str(args.motion)]
    for option in ("param", "add"):
        for value in getattr(args, option, None) or ():
            words.append(f"--{option} {value}")
    defaults = argparse.ArgumentParser()
    add_trace_arguments(defaults)
    for name, default in vars(defaults.parse_args([])).items():
        value = getattr(args, name, default)
        if value != default:
            words.append(f"--{name.replace('_', '-')} {value}")
    return " ".join(words)


__all__ = ["phantom_words", "reference_words"]
