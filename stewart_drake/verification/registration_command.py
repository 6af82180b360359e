"""A tracker's registration by a known motion, fitted and written (``stewart-drake calibrate
--register MEASURED.csv --out REG.yaml``): the fit of :mod:`~.registration_motion`, refused
when the frames it gives are too uncertain, then the REG.yaml of
:func:`~stewart_drake.calibration.registration_file.motion_frames_yaml` that every later
``verify --registration`` takes."""

from __future__ import annotations

import numpy as np

from ..base.errors import InvalidConfigError
from .measured_motion import MeasuredMotion
from .registration_motion import fit_registration


def save_registration(
    reference, measured: MeasuredMotion, path, clock_offset_s, max_latency_s, max_gap_s
) -> str:
    """Fit the tracker's frames to ``measured``, a run of the known ``reference``
    (:func:`~.registration_motion.fit_registration`), and write them to ``path`` as a REG.yaml
    (:func:`~stewart_drake.calibration.registration_file.motion_frames_yaml`, each frame with its
    standard deviation); ``stewart-drake calibrate --register``.

    Args:
        reference: the registration motion asked for. measured: the tracker's run of it.
        path: the REG.yaml to write (atomically; the caller refuses one that exists).
        clock_offset_s, max_latency_s, max_gap_s: as
            :func:`~.registration_motion.fit_registration` takes them.
    Returns:
        the line that says what was registered and how well.
    Raises:
        InvalidConfigError: what the fit refuses; frames too uncertain to be written.
    """
    from pathlib import Path

    from pydrake.math import RigidTransform, RotationMatrix

    from ..base.fileio import atomic_write
    from ..calibration.registration_file import MAX_MARKER_SIGMA, motion_frames_yaml

    fit = fit_registration(reference, measured, clock_offset_s, max_latency_s, max_gap_s)
    for what, sigma in (("the tracker's frame", fit.sigma_B), ("the marker's", fit.sigma_M)):
        if sigma[0] > MAX_MARKER_SIGMA[0] or sigma[1] > MAX_MARKER_SIGMA[1]:
            raise InvalidConfigError(
                f"{measured.path}: {what} is known to +- {sigma[0] * 1e3:.3g} mrad, "
                f"{sigma[1] * 1e3:.3g} mm only: measure a longer run of the registration motion"
            )
    X_BT = RigidTransform(RotationMatrix(fit.R_BT), fit.p_BT)
    X_PM = RigidTransform(RotationMatrix(fit.R_PM), fit.p_PM)
    text = motion_frames_yaml(
        X_BT.inverse(), X_PM, fit.sigma_B, fit.sigma_M, fit.rms_m, fit.words()
    )
    atomic_write(Path(path), lambda f: f.write(text.encode()))
    return (
        f"registered the tracker: {fit.words()}; the tracker's frame known to +- "
        f"{fit.sigma_B[0] * 1e6:.3g} urad, {fit.sigma_B[1] * 1e6:.3g} um, the marker "
        f"{np.linalg.norm(fit.p_PM) * 1e3:.4g} mm from the platform's origin (+- "
        f"{fit.sigma_M[1] * 1e6:.3g} um). This run is not judged: a frame fitted to a motion "
        f"absorbs its errors. Judge later runs with --registration {path}"
    )


__all__ = ["save_registration"]
