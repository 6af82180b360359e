import importlib.util

import numpy as np
import pytest

from stewart_drake.model import kinematics
from stewart_drake.model.geometry import X_HOME, StewartGeometry

#: torch is the [train] extra, a CPU wheel only for Python 3.11 here: tests that train skip
#: without it (CI runs the suite on the newest Python without it).
HAS_TORCH = importlib.util.find_spec("torch") is not None
needs_torch = pytest.mark.skipif(not HAS_TORCH, reason="needs torch (the [train] extra)")


@pytest.fixture(scope="session")
def geometry():
    return StewartGeometry()


def random_reachable_poses(geometry, n, seed=0, margin=0.95):
    """n poses around home whose legs all have |ratio| < margin (deterministic)."""
    rng = np.random.default_rng(seed)
    scale = np.array([0.25, 0.25, 0.35, 0.04, 0.04, 0.03])
    out = []
    while len(out) < n:
        x = X_HOME + rng.uniform(-1, 1, (4 * n, 6)) * scale
        ok = np.all(np.abs(kinematics.leg_reach_ratio(geometry, x)) < margin, axis=1)
        cond = np.linalg.cond(kinematics.jacobian(geometry, x[ok]))
        out.extend(x[ok][cond < 200])
    return np.array(out[:n])


@pytest.fixture(scope="session")
def random_poses(geometry):
    return random_reachable_poses(geometry, 200)


def install_plugin(site, package: str, entry_points: dict, source: str):
    """Install in folder ``site`` a distribution ``package`` (a ``.dist-info``, as pip leaves one)
    whose module ``package`` has ``source`` and whose entry points of the group
    ``stewart_drake.controllers`` are ``{name: "module:attribute"}``; put ``site`` on the path
    to see it. Returns ``site``."""
    info = site / f"{package}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {package}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(
        "[stewart_drake.controllers]\n"
        + "".join(f"{name} = {target}\n" for name, target in entry_points.items())
    )
    (site / f"{package}.py").write_text(source)
    return site


@pytest.fixture
def feedforward_fault(monkeypatch):
    """``feedforward_fault(fn)``: from then on every LQI acts on ``fn(T_ff)`` instead of the
    feed-forward on its port (fault injection at the one place the LQI reads its ports,
    ``LqiController.inputs``). ``fn`` may also raise."""
    from stewart_drake.control.lqi import LqiController

    def install(fn):
        original = LqiController.inputs

        def faulty(self, context):
            u = original(self, context)
            u[self.layout.T_ff] = fn(u[self.layout.T_ff])
            return u

        monkeypatch.setattr(LqiController, "inputs", faulty)

    return install


def write_trace(path, t, columns: dict, gap=None, time_header: str = "t [s]"):
    """Write a trace CSV: the time column then ``columns`` ({"SI [mm]": values}), leaving out
    the rows strictly inside ``gap`` (start, end) s. Returns ``path``."""
    keep = np.ones(len(t), bool) if gap is None else ~((t > gap[0]) & (t < gap[1]))
    lines = [",".join([time_header] + list(columns))]
    lines += [
        ",".join([f"{t[k]:.5f}"] + [f"{v[k]:.6f}" for v in columns.values()])
        for k in np.flatnonzero(keep)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path
