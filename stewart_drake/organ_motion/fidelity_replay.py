"""The 3-D replay of a reproduction (`stewart-drake reproduce --html`): the robot as run, the
reference as a ghost and the error of each instant against the tolerance, in one HTML file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..base.errors import InvalidConfigError
from ..viz.visualize import REPLAY_FPS, offline_meshcat, record_states, write_static_html


def reproduction_html(
    rep,
    geometry,
    path: str | Path,
    tolerance: tuple,
    fps: float = REPLAY_FPS,
    meshcat=None,
    plan=None,
) -> Path:
    """Write the 3-D replay of a reproduction (``stewart-drake reproduce --html``) as a
    standalone HTML file: the robot from the run's plant-state log (every
    ``state_log_period_s``), the reference as a ghost, a marker above the ghost coloured by the
    translation error of that instant against the tolerance
    (:func:`~.visualize.error_colour`), and a caption with the motion, the verdict and the
    colours' meaning.

    Args:
        rep: the :class:`~stewart_drake.organ_motion.reproduction.Reproduction`.
        geometry: the robot that was simulated (the plan's ``plant_geometry``).
        path: the .html to write. tolerance: (m, rad) the report's tolerance.
        fps: frames per s. meshcat: a Meshcat to record into (default: :func:`offline_meshcat`).
        plan: the run's :class:`~stewart_drake.run.plan.RunPlan`, needed when its servos have
            gear play (its plant's states are drawn by the cranks' angles), else None.
    Returns:
        the path written.
    Raises:
        InvalidConfigError: a result without its plant-state log (a file saved before it had
            one).
    """
    from .fidelity import verdict

    r = rep.result
    if r.state is None:
        raise InvalidConfigError(
            "this result has no plant-state log to replay: run the reproduction again"
        )
    x_d = np.concatenate(rep.reference.evaluate(r.t_state), axis=1)
    # The translation error at each state sample, from the pose log at the same instant.
    j = np.clip(np.searchsorted(r.t, r.t_state - 1e-9), 0, r.t.size - 1)
    e = np.linalg.norm(np.subtract(r.x[j, 3:6], r.x_d[j, 3:6], dtype=float), axis=1)
    meshcat = meshcat if meshcat is not None else offline_meshcat()
    states = r.state
    if plan is not None and plan.servo is not None and plan.servo.backlash_rad > 0:
        from pydrake.systems.framework import DiagramBuilder

        from ..plant.closed_chain import states_without_play
        from ..station.station import add_station_plant

        plant, _, handles = add_station_plant(DiagramBuilder(), plan)
        states = states_without_play(plant, handles, states)
    record_states(meshcat, geometry, r.t_state, states, fps, x_d=x_d, error=(e, tolerance[0]))
    tol_um = tolerance[0] * 1e6
    caption = (
        f"{rep.name}: {verdict(rep.fidelity, tolerance, rep.comparison())[1]}\n"
        f"blue ghost: the reference; the sphere above it: the translation error at that "
        f"instant, green <= {0.5 * tol_um:.3g} um, amber <= {tol_um:.3g} um, red beyond"
    )
    return write_static_html(meshcat, path, caption)
