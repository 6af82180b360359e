"""The robot as built, leg by leg: the per-leg parameters a calibration identifies, their
inverse kinematics and its derivatives.

For leg i of a nominal :class:`~stewart_drake.robot.geometry.StewartGeometry` (its ``P_B``,
``p_E``, ``crank_length``, ``rod_length``, ``crank_angles_deg``):

    P_i = P_B[i] + pivot_offsets_m[i]              crank pivot, base frame B, m
    p_i = p_E[i] + platform_offsets_m[i]           platform joint, platform frame E, m
    d_i = (cos beta_i, sin beta_i, 0)              beta_i = crank_angles_deg[i] (degrees)
    w_i = cos t_i z + sin t_i (d_i x z)            t_i = shaft_tilts_rad[i]
    tip_i(theta) = P_i + a_i (cos theta d_i + sin theta w_i)    a_i = crank_lengths_m[i]
    |q_i - tip_i(theta_i)| = s_i,  q_i = p_BE + R_BE p_i         s_i = rod_lengths_m[i]
    reading_i = theta_i + encoder_offsets_rad[i]

The shaft tilt turns the crank's plane about d_i (0: the vertical plane of today's robot); a
crank azimuth error is a change of ``crank_angles_deg``, which turns the plane about the
vertical through P_i. The closed form is that of :func:`~stewart_drake.robot.kinematics.ik` with
z replaced by w_i: L = |l|^2 - (s^2 - a^2), M = 2 a l.w, N = 2 a l.d with l = q - P, and
theta = asin(L / sqrt(M^2 + N^2)) - atan2(N, M), the same branch. With every deviation zero it is
:func:`~stewart_drake.robot.kinematics.ik` (a test checks to 1e-13).

The identification works on a vector of 66 deviations from the nominal robot
(:data:`PARAMETER_KINDS`, in that order, each kind leg-major): the pivots' and platform joints'
offsets (18 each, m), the crank and rod lengths' deviations (6 each, m), the shaft tilts (rad),
the crank azimuths' deviations (rad, not degrees) and the encoder offsets (rad).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..base.checks import as_array, as_poses
from ..base.errors import InvalidGeometryError, UnreachablePoseError
from .geometry import StewartGeometry
from .kinematics import ik_angles, rotation_rpy

_Z = np.array([0.0, 0.0, 1.0])

#: The kinds of per-leg parameter, in the order of the deviation vector: (field of
#: :class:`LegParameters`, entries per leg, unit of the deviation in the vector).
PARAMETER_KINDS = (
    ("pivot_offsets_m", 3, "m"),
    ("platform_offsets_m", 3, "m"),
    ("crank_lengths_m", 1, "m"),
    ("rod_lengths_m", 1, "m"),
    ("shaft_tilts_rad", 1, "rad"),
    ("crank_angles_deg", 1, "rad"),
    ("encoder_offsets_rad", 1, "rad"),
)
#: Number of identified deviations: 11 per leg.
N_PARAMETERS = 6 * sum(n for _, n, _ in PARAMETER_KINDS)


def parameter_names() -> tuple[str, ...]:
    """(66,) names of the deviation vector's entries, e.g. ``pivot_offsets_m[2].y``,
    ``crank_angles_deg[4]`` (its deviation, in rad in the vector)."""
    names = []
    for kind, width, _ in PARAMETER_KINDS:
        for leg in range(6):
            if width == 3:
                names += [f"{kind}[{leg}].{axis}" for axis in "xyz"]
            else:
                names.append(f"{kind}[{leg}]")
    return tuple(names)


def parameter_legs() -> np.ndarray:
    """(66,) the leg of each entry of the deviation vector."""
    return np.concatenate([np.repeat(np.arange(6), width) for _, width, _ in PARAMETER_KINDS])


def parameter_kinds() -> tuple[str, ...]:
    """(66,) the kind (a field of :class:`LegParameters`) of each entry of the vector."""
    return tuple(kind for kind, width, _ in PARAMETER_KINDS for _ in range(6 * width))


@dataclass(frozen=True)
class LegParameters:
    """Every leg's geometry and encoder zero, as built (module docstring).

    Attributes:
        pivot_offsets_m: (6, 3) added to the nominal crank pivots P_B, base frame, m.
        platform_offsets_m: (6, 3) added to the nominal platform joints p_E, frame E, m.
        crank_lengths_m: (6,) a_i, m.  rod_lengths_m: (6,) s_i, m.
        shaft_tilts_rad: (6,) t_i, the crank plane turned about d_i, rad.
        crank_angles_deg: (6,) beta_i, azimuth of d_i, degrees (the geometry's field, per leg).
        encoder_offsets_rad: (6,) what each encoder reads at theta_i = 0, rad.
    Raises:
        InvalidGeometryError: a field of the wrong shape, not finite, or a length <= 0, or a
            rod not longer than its crank (names the field).
    """

    pivot_offsets_m: np.ndarray
    platform_offsets_m: np.ndarray
    crank_lengths_m: np.ndarray
    rod_lengths_m: np.ndarray
    shaft_tilts_rad: np.ndarray
    crank_angles_deg: np.ndarray
    encoder_offsets_rad: np.ndarray

    def __post_init__(self):
        for name, width, _ in PARAMETER_KINDS:
            shape = (6, 3) if width == 3 else (6,)
            value = as_array(name, getattr(self, name), shape=shape, error=InvalidGeometryError)
            value = value.copy()
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if np.any(self.crank_lengths_m <= 0) or np.any(self.rod_lengths_m <= self.crank_lengths_m):
            raise InvalidGeometryError(
                "crank_lengths_m must be > 0 and each of rod_lengths_m longer than its crank, "
                f"got {self.crank_lengths_m.tolist()} and {self.rod_lengths_m.tolist()}"
            )

    @classmethod
    def nominal(cls, geometry: StewartGeometry) -> LegParameters:
        """The legs of ``geometry`` exactly: offsets, tilts and encoder zeros 0."""
        return cls(
            pivot_offsets_m=np.zeros((6, 3)),
            platform_offsets_m=np.zeros((6, 3)),
            crank_lengths_m=np.full(6, geometry.crank_length),
            rod_lengths_m=np.full(6, geometry.rod_length),
            shaft_tilts_rad=np.zeros(6),
            crank_angles_deg=np.array(geometry.crank_angles_deg, dtype=float),
            encoder_offsets_rad=np.zeros(6),
        )

    @classmethod
    def of(cls, geometry: StewartGeometry) -> LegParameters:
        """The legs of ``geometry`` as it is, its per-leg fields included (null ones as drawn),
        about its symmetric robot (``geometry`` with every per-leg field null): for a symmetric
        ``geometry``, :meth:`nominal` exactly."""

        def given(name: str, shape: tuple) -> np.ndarray:
            value = getattr(geometry, name)
            return np.zeros(shape) if value is None else np.array(value, dtype=float)

        return cls(
            pivot_offsets_m=given("pivot_offsets_m", (6, 3)),
            platform_offsets_m=given("platform_offsets_m", (6, 3)),
            crank_lengths_m=np.array(geometry.crank_lengths),
            rod_lengths_m=np.array(geometry.rod_lengths),
            shaft_tilts_rad=given("shaft_tilts_rad", (6,)),
            crank_angles_deg=np.array(geometry.crank_angles_deg, dtype=float),
            encoder_offsets_rad=given("encoder_offsets_rad", (6,)),
        )

    def geometry(self, nominal: StewartGeometry) -> StewartGeometry:
        """``nominal`` with these legs as its per-leg fields (and crank azimuths): the robot
        the rest of the package simulates, whose inverse kinematics plus encoder offsets gives
        :func:`readings`.

        Raises:
            InvalidGeometryError: a deviation beyond the geometry's bounds (it names the field).
        """
        return nominal.replace(
            pivot_offsets_m=tuple(map(tuple, self.pivot_offsets_m.tolist())),
            platform_offsets_m=tuple(map(tuple, self.platform_offsets_m.tolist())),
            crank_lengths_m=tuple(self.crank_lengths_m.tolist()),
            rod_lengths_m=tuple(self.rod_lengths_m.tolist()),
            shaft_tilts_rad=tuple(self.shaft_tilts_rad.tolist()),
            crank_angles_deg=tuple(self.crank_angles_deg.tolist()),
            encoder_offsets_rad=tuple(self.encoder_offsets_rad.tolist()),
        )

    def deviation(self, nominal: LegParameters) -> np.ndarray:
        """(66,) this robot's deviation vector from ``nominal`` (module docstring; the crank
        azimuths' in rad)."""
        parts = []
        for name, _, _ in PARAMETER_KINDS:
            delta = np.asarray(getattr(self, name)) - np.asarray(getattr(nominal, name))
            parts.append(np.deg2rad(delta).ravel() if name == "crank_angles_deg" else delta.ravel())
        return np.concatenate(parts)

    def shifted(self, delta) -> LegParameters:
        """These legs with the deviation vector ``delta`` (66,) added."""
        delta = as_array("deviation vector", delta, shape=(N_PARAMETERS,))
        fields, start = {}, 0
        for name, width, _ in PARAMETER_KINDS:
            part = delta[start : start + 6 * width]
            start += 6 * width
            base = np.asarray(getattr(self, name))
            if name == "crank_angles_deg":
                part = np.rad2deg(part)
            fields[name] = base + part.reshape(base.shape)
        return LegParameters(**fields)


@dataclass(frozen=True)
class LegFrames:
    """The per-leg vectors of one robot (:func:`leg_frames`), base frame unless said.

    Attributes:
        P: (6, 3) pivots, m.  p: (6, 3) platform joints in E, m.  d: (6, 3) crank directions at
        theta = 0.  w: (6, 3) the crank plane's second axis.  a, s: (6,) crank and rod lengths,
        m.  offsets: (6,) encoder offsets, rad.  tilt: (6,) shaft tilts, rad.
    """

    P: np.ndarray
    p: np.ndarray
    d: np.ndarray
    w: np.ndarray
    a: np.ndarray
    s: np.ndarray
    offsets: np.ndarray
    tilt: np.ndarray


def leg_frames(geometry: StewartGeometry, legs: LegParameters) -> LegFrames:
    """The per-leg vectors of the robot ``legs`` built on the nominal ``geometry``."""
    beta = np.deg2rad(np.asarray(legs.crank_angles_deg, dtype=float))
    d = np.stack([np.cos(beta), np.sin(beta), np.zeros(6)], axis=1)
    t = np.asarray(legs.shaft_tilts_rad)[:, None]
    w = np.cos(t) * _Z + np.sin(t) * np.cross(d, _Z)
    return LegFrames(
        P=geometry.P_B + legs.pivot_offsets_m,
        p=geometry.p_E + legs.platform_offsets_m,
        d=d,
        w=w,
        a=np.asarray(legs.crank_lengths_m),
        s=np.asarray(legs.rod_lengths_m),
        offsets=np.asarray(legs.encoder_offsets_rad),
        tilt=np.asarray(legs.shaft_tilts_rad),
    )


def leg_ik_unchecked(frames: LegFrames, x) -> tuple[np.ndarray, np.ndarray]:
    """Motor angles of poses x (..., 6) for the legs ``frames``, without raising.

    Returns:
        theta: (..., 6) rad, NaN where a leg cannot close; the branch of
            :func:`~stewart_drake.robot.kinematics.ik`.
        ratio: (..., 6) L / sqrt(M^2 + N^2).
    """
    x = np.asarray(x, dtype=float)
    R = rotation_rpy(x[..., :3])
    q = np.einsum("...jk,ik->...ij", R, frames.p) + x[..., None, 3:6]
    l = q - frames.P
    a, s = frames.a, frames.s
    L = np.sum(l * l, axis=-1) - (s * s - a * a)
    M = 2.0 * a * np.sum(l * frames.w, axis=-1)
    N = 2.0 * a * np.sum(l * frames.d, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = L / np.hypot(M, N)
    return ik_angles(ratio, M, N), ratio


def leg_ik(geometry: StewartGeometry, legs: LegParameters, x) -> np.ndarray:
    """Motor angles theta (..., 6) in rad of poses x (..., 6) [rad, m] for the robot ``legs``.

    Raises:
        UnreachablePoseError: a leg cannot close (names the first pose and leg).
        InvalidConfigError: x not (..., 6) or not finite.
    """
    x = as_poses("pose x", x)
    theta, ratio = leg_ik_unchecked(leg_frames(geometry, legs), x)
    bad = ~(np.abs(ratio) <= 1.0)
    if np.any(bad):
        flat = bad.reshape(-1, 6)
        k = int(np.argmax(flat.any(axis=1)))
        leg = int(np.argmax(flat[k]))
        raise UnreachablePoseError(leg, ratio.reshape(-1, 6)[k, leg], pose=x.reshape(-1, 6)[k])
    return theta


def readings(geometry: StewartGeometry, legs: LegParameters, x) -> np.ndarray:
    """(..., 6) what the encoders read at poses x (..., 6): :func:`leg_ik` plus the encoder
    offsets, rad (not quantized; :mod:`~.tracker` quantizes).

    Raises:
        as :func:`leg_ik`.
    """
    return leg_ik(geometry, legs, x) + np.asarray(legs.encoder_offsets_rad)


@dataclass(frozen=True)
class LegDerivatives:
    """Derivatives of the readings at poses (N, 6) (:func:`derivatives`).

    Attributes:
        theta: (N, 6) motor angles, rad.
        parameters: (N, 6, 66) d reading / d deviation vector (units of the vector).
        pose: (N, 6, 6) d reading / d [rotation vector delta (base frame), p_BE], where a
            measured pose is R = exp([delta]x) R_true, p = p_true + dp: rad per rad and per m.
    """

    theta: np.ndarray
    parameters: np.ndarray
    pose: np.ndarray


def derivatives(geometry: StewartGeometry, legs: LegParameters, x) -> LegDerivatives:
    """Analytic derivatives of the readings of the robot ``legs`` at poses x (N, 6).

    From |ell|^2 = s^2 with ell = q - tip: d theta = (ell . (dq - dtip) - s ds) / (a ell . e),
    e = -sin theta d + cos theta w the tip's direction of motion (tests compare with finite
    differences).

    Raises:
        UnreachablePoseError, InvalidConfigError: as :func:`leg_ik`.
    """
    x = as_poses("pose x", x).reshape(-1, 6)
    f = leg_frames(geometry, legs)
    theta = leg_ik(geometry, legs, x)
    R = rotation_rpy(x[:, :3])
    r = np.einsum("njk,ik->nij", R, f.p)  # lever arms R p_i, (N, 6, 3)
    q = r + x[:, None, 3:6]
    c, s_ = np.cos(theta)[..., None], np.sin(theta)[..., None]
    radial = c * f.d + s_ * f.w  # tip direction from the pivot, (N, 6, 3)
    ell = q - (f.P + f.a[:, None] * radial)
    e = -s_ * f.d + c * f.w
    den = f.a * np.sum(ell * e, axis=-1)  # (N, 6)
    g = ell / den[..., None]  # d theta / d q
    n = len(x)
    dpar = np.zeros((n, 6, N_PARAMETERS))
    dd_dbeta = np.cross(_Z, f.d)  # (6, 3)
    sin_t, cos_t = np.sin(f.tilt)[:, None], np.cos(f.tilt)[:, None]
    dw_dbeta = sin_t * np.cross(dd_dbeta, _Z)
    dw_dt = -sin_t * _Z + cos_t * np.cross(f.d, _Z)
    columns = {
        "pivot_offsets_m": -g,
        "platform_offsets_m": np.einsum("nij,nki->nkj", R, g),  # R^T g per leg
        "crank_lengths_m": -np.sum(g * radial, axis=-1),
        "rod_lengths_m": -f.s / den,
        "shaft_tilts_rad": -f.a * s_[..., 0] * np.sum(g * dw_dt, axis=-1),
        "crank_angles_deg": -f.a * np.sum(g * (c * dd_dbeta + s_ * dw_dbeta), axis=-1),
        "encoder_offsets_rad": np.ones((n, 6)),
    }
    start = 0
    for name, width, _ in PARAMETER_KINDS:
        value = columns[name]
        for leg in range(6):
            if width == 3:
                dpar[:, leg, start + 3 * leg : start + 3 * leg + 3] = value[:, leg]
            else:
                dpar[:, leg, start + leg] = value[:, leg]
        start += 6 * width
    dpose = np.concatenate([np.cross(r, g), g], axis=-1)  # delta . (r x g), dp . g
    return LegDerivatives(theta=theta, parameters=dpar, pose=dpose)
