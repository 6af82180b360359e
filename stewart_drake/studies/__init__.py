"""The studies: each a feature run over a set of motions, robots or settings, whose tables and
figures are written into docs/ by a tool (``python tools/organ_motion_tables.py``,
``tools/stream_prediction_table.py``, ``tools/stream_selection_table.py``), apart from the
features they study, which never import them.

- :mod:`.fidelity_study`: the library's motions reproduced, learning and not, against the
  fidelity goal (docs/organ_motion.md's tables);
- :mod:`.trace_study`: recorded patients' traces on the robots, the feed-forward learned from
  zero and from the library's model;
- :mod:`.stream_study`, :mod:`.stream_sources`, :mod:`.stream_selection`: a motion streamed late
  and followed with each predictor, over the sources of motions and the choice of the
  predictor's settings left out in turn.

A new study goes here: a module with its runs (through :mod:`stewart_drake.execution.runners`),
its tables (:func:`stewart_drake.base.tables.markdown_lines`) written between its markers
(:func:`stewart_drake.base.fileio.write_between_markers`), and a tool in tools/ that runs it.
"""


def simulated_line(results: dict, runs: str, where: str = "") -> str:
    """The line under a study's tables: how many ``runs`` (its results' dict entries), the
    seconds simulated and the simulation's wall time (each run's "sim_s" and "wall_s"),
    ``where`` said after it (" (two processes)")."""
    done = [v for v in results.values() if isinstance(v, dict)]
    simulated, wall = sum(v["sim_s"] for v in done), sum(v["wall_s"] for v in done)
    return (
        f"{len(done)} {runs}, {simulated:.0f} s simulated in {wall:.0f} s of simulation wall "
        f"time{where}."
    )
