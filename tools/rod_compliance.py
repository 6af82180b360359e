"""Whether the rods' axial compliance matters: the pose change it causes along the paper
manoeuvre, printed as the table in docs/calibration.md ("The rods' axial compliance").

    python tools/rod_compliance.py [--modulus-gpa 70]

Each rod is taken as a solid round bar of the geometry's ``rod_radius`` and ``rod_length``
(the geometry's ``rod_mass`` gives it a density of 2,520 kg/m^3: aluminium), of Young's modulus
E, so its axial stiffness is k = E pi r^2 / L. Its axial force f_i comes from the crank's
torque by virtual work with the rod massless, T_i = f_i d(l_i)/d(theta_i), the torques being
the closed chain's inverse dynamics along the manoeuvre (:func:`~stewart_drake.robot.statics.
inverse_dynamics_torques`, the cranks' and rods' inertia included, so the forces are an upper
bound). Stretched by f_i / k with the cranks held, the rods move the platform by dx solving
(dl/dx) dx = f / k. The rod ends' own compliance and play are not modelled.
"""

import argparse

import numpy as np

from stewart_drake.base.tables import markdown_row
from stewart_drake.references.trajectories import paper_manoeuvre
from stewart_drake.robot import kinematics, statics
from stewart_drake.robot.geometry import StewartGeometry


def rod_lengths(geometry: StewartGeometry, x: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """(6,) the distance between each platform joint at pose x and its crank tip at theta, m."""
    q_B, _ = kinematics.platform_joints(geometry, x)
    return np.linalg.norm(q_B - geometry.crank_tips(theta), axis=-1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modulus-gpa", type=float, default=70.0, help="the rods' E, GPa")
    args = parser.parse_args()
    g = StewartGeometry()
    k = args.modulus_gpa * 1e9 * np.pi * g.rod_radius**2 / g.rod_length
    x, x_dot, x_ddot = paper_manoeuvre().evaluate(np.arange(0.0, 10.0, 0.05))
    torques = statics.inverse_dynamics_torques(g, x, x_dot, x_ddot)
    h, eye = 1e-7, np.eye(6)
    forces, moves = [], []
    for x_k, T_k in zip(x, torques):
        theta = kinematics.ik(g, x_k)
        dl_dtheta = np.array(
            [
                (rod_lengths(g, x_k, theta + h * e) - rod_lengths(g, x_k, theta - h * e))[i]
                / (2 * h)
                for i, e in enumerate(eye)
            ]
        )
        dl_dx = np.column_stack(
            [
                (rod_lengths(g, x_k + h * e, theta) - rod_lengths(g, x_k - h * e, theta)) / (2 * h)
                for e in eye
            ]
        )
        f = T_k / dl_dtheta
        forces.append(f)
        moves.append(np.linalg.solve(dl_dx, f / k))
    forces, moves = np.array(forces), np.array(moves)
    swing = moves.max(axis=0) - moves.min(axis=0)
    rows = [
        [
            f"rod axial stiffness (E = {args.modulus_gpa:g} GPa, solid, "
            f"r = {g.rod_radius * 1e3:g} mm, L = {g.rod_length * 1e3:g} mm)",
            f"{k:.3g} N/m",
        ],
        [
            "rod axial force, peak (mean magnitude)",
            f"{np.abs(forces).max():.2f} N ({np.abs(forces).mean():.2f} N)",
        ],
        [
            "platform moved by the stretch, peak: translation, rotation",
            f"{np.abs(moves[:, 3:]).max() * 1e6:.2f} um, "
            f"{np.abs(moves[:, :3]).max() * 1e6:.2f} urad",
        ],
        [
            "its change over the manoeuvre, largest axis: translation, rotation",
            f"{swing[3:].max() * 1e6:.2f} um, {swing[:3].max() * 1e6:.2f} urad",
        ],
    ]
    for row in rows:
        print(markdown_row(row))


if __name__ == "__main__":
    main()
