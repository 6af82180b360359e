import importlib.metadata
import importlib.util
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

#: Where the suite keeps compiled bytecode when the environment asks Python not to write it
#: beside the sources (PYTHONDONTWRITEBYTECODE, as on our CI machines): pytest's own cache
#: folder, which the suite writes anyway. Without it every worker re-rewrites the assertions of
#: 95 test modules (about 6 s each) and every command a test starts compiles the package again
#: (0.3 s a process).
PYCACHE_PREFIX = Path(__file__).resolve().parent.parent / ".pytest_cache" / "pycache"


def _cache_bytecode_out_of_the_tree() -> None:
    if not sys.dont_write_bytecode or sys.pycache_prefix is not None:
        return
    sys.pycache_prefix = str(PYCACHE_PREFIX)
    sys.dont_write_bytecode = False
    # The workers (-n 2), the commands and the notebooks' kernels started from here inherit it.
    os.environ["PYTHONPYCACHEPREFIX"] = str(PYCACHE_PREFIX)
    os.environ.pop("PYTHONDONTWRITEBYTECODE", None)


_cache_bytecode_out_of_the_tree()


def _tuned_allocator_for_the_workers() -> None:
    """Size glibc's thread cache for the plant's step in the processes the suite starts (the
    workers of -n 2, the commands, the notebooks' kernels), as the command does for itself
    (stewart_drake/base/allocator.py): their CPU, not their results."""
    from stewart_drake.base.allocator import tuned_environment

    env = tuned_environment(os.environ)
    if env is not None:
        os.environ["GLIBC_TUNABLES"] = env["GLIBC_TUNABLES"]


_tuned_allocator_for_the_workers()

from stewart_drake.robot import kinematics
from stewart_drake.robot.geometry import X_HOME, StewartGeometry

#: The module each extra of pyproject.toml brings that its tests need, and the lowest version
#: they accept (None: any).
EXTRAS = {
    "train": ("torch", None),
    "mujoco": ("mujoco", "4.0"),
    "ray": ("ray", None),
    "dask": ("distributed", None),
    "analysis": ("control", None),
    "robot": ("dynamixel_sdk", None),
    "docs": ("pdoc", "16.0"),
}


def _version_tuple(text: str) -> tuple:
    return tuple(int(p) for p in text.split(".")[:3] if p.isdigit())


def extra_missing(extra: str) -> str | None:
    """Why the tests of ``extra`` cannot run here (the install command that brings it), or None
    when its module is installed (at the version the tests need). Found without importing the
    module: a skip costs nothing."""
    module, minimum = EXTRAS[extra]
    install = f'pip install -e ".[{extra}]"'
    if importlib.util.find_spec(module) is None:
        return f"needs the {extra} extra: {install}"
    if minimum is not None:
        try:
            version = importlib.metadata.version(module)
        except importlib.metadata.PackageNotFoundError:
            version = "0"
        if _version_tuple(version) < _version_tuple(minimum):
            return f"needs the {extra} extra ({module} >= {minimum}, found {version}): {install}"
    return None


def needs_extra(extra: str):
    """A mark: skip the test, before any fixture starts what it would need, when ``extra`` is
    not installed, naming the command that installs it."""
    reason = extra_missing(extra)
    return pytest.mark.skipif(reason is not None, reason=reason or "")


def require_extra(extra: str) -> None:
    """At a test module's top: skip the whole module when ``extra`` is not installed."""
    reason = extra_missing(extra)
    if reason is not None:
        pytest.skip(reason, allow_module_level=True)


#: torch is the [train] extra, a CPU wheel only for Python 3.11 here: tests that train skip
#: without it (CI runs the suite on the newest Python without it).
HAS_TORCH = extra_missing("train") is None
needs_torch = needs_extra("train")


# -- the tiers (pyproject.toml, [tool.pytest.ini_options]; docs/development.md) -----------------

#: Test modules whose tests run the closed loop in process (a Simulator, an experiment, a
#: study): the `loop` tier. Every other test not marked `system` or `slow` is a `unit` test.
LOOP_MODULES = {
    "test_accuracy",
    "test_crank_servo_loop",
    "test_error_budget",
    "test_surrogate_loop",
    "test_closed_loop",
    "test_design_confirm",
    "test_distributed",
    "test_evaluation",
    "test_experiments",
    "test_feedforward_tuning",
    "test_fig7",
    "test_guard",
    "test_hardware",
    "test_hardware_station",
    "test_ilc",
    "test_stream_reproduce",
    "test_lcm_config",
    "test_learning",
    "test_lqi",
    "test_organ_motion_phantom",
    "test_pd",
    "test_per_leg_geometry",
    "test_report_labels",
    "test_reproduce",
    "test_robot_as_built",
    "test_station",
    "test_studies",
    "test_tuner_pipeline",
    "test_tuner_study",
    "test_visualize",
}


#: Test modules whose every test is a system test: the robot's bus emulator, its plant stepped
#: at real time in a thread, talked to over a pseudo-terminal.
SYSTEM_MODULES = {
    "test_calibration_bus",
    "test_dynamixel_bus",
    "test_hardware_station",
    "test_robot_follow",
    "test_robot_input",
    "test_robot_motions",
    "test_robot_safety",
    "test_robot_session",
    "test_robot_surrogate",
}


def pytest_collection_modifyitems(config, items):
    """Give every test its tier: `slow` and `system` as marked (`system` too for the modules of
    :data:`SYSTEM_MODULES`), `loop` for the modules of :data:`LOOP_MODULES`, `unit` for the
    rest."""
    for item in items:
        if item.get_closest_marker("slow"):
            continue
        module = Path(str(item.fspath)).stem
        if module in SYSTEM_MODULES:
            item.add_marker(pytest.mark.system)
        if item.get_closest_marker("system"):
            continue
        item.add_marker(pytest.mark.loop if module in LOOP_MODULES else pytest.mark.unit)


def pytest_configure(config):
    """Compile the LQI's step and the crank servo's once, in the controlling process, before
    any worker starts (``-n 2``): two workers compiling at once each pay the minute, and every
    command a test
    starts would say on stderr that it is compiling. A worker (``workerinput``) finds the cache
    warm."""
    if hasattr(config, "workerinput") or config.option.help or config.option.collectonly:
        return
    if "stewart_drake.control.lqi.kernels" in sys.modules:
        return
    t0 = time.monotonic()
    import stewart_drake.control.lqi.kernels  # noqa: F401  (compiles, or loads the cache)
    import stewart_drake.control.servo.kernels  # noqa: F401  (the bus's controller, likewise)

    if time.monotonic() - t0 > 5.0:
        print(f"compiled the LQI's step into numba's cache in {time.monotonic() - t0:.0f} s")


@pytest.fixture(scope="session")
def geometry():
    return StewartGeometry()


def drawn_robot(seed: int = 49, encoders: bool = True) -> StewartGeometry:
    """A robot as built: +-0.5 mm on every joint position, +-0.2 mm on the crank lengths,
    +-0.3 mm on the rod lengths, +-5 mrad of shaft tilt and (``encoders``) of encoder zero."""
    nominal = StewartGeometry()
    rng = np.random.default_rng(seed)
    return nominal.replace(
        pivot_offsets_m=rng.uniform(-5e-4, 5e-4, (6, 3)),
        platform_offsets_m=rng.uniform(-5e-4, 5e-4, (6, 3)),
        crank_lengths_m=nominal.crank_length + rng.uniform(-2e-4, 2e-4, 6),
        rod_lengths_m=nominal.rod_length + rng.uniform(-3e-4, 3e-4, 6),
        shaft_tilts_rad=rng.uniform(-5e-3, 5e-3, 6),
        encoder_offsets_rad=rng.uniform(-5e-3, 5e-3, 6) if encoders else None,
    )


def assert_plant_has_the_legs_of(plant, context, handles, geometry) -> None:
    """Read back from Drake: each crank's pivot and motor axis in the world where ``geometry``
    puts them (P_B, u_B), and each rod's ball joint at [a_i, 0, 0] in its crank's frame (to
    the SDF's 12 significant digits)."""
    pivots = [plant.EvalBodyPoseInWorld(context, c).translation() for c in handles.cranks]
    np.testing.assert_allclose(np.array(pivots), geometry.P_B, rtol=0, atol=1e-12)
    axes = [
        plant.EvalBodyPoseInWorld(context, c).rotation().multiply(j.revolute_axis())
        for c, j in zip(handles.cranks, handles.motors)
    ]
    np.testing.assert_allclose(np.array(axes), geometry.u_B, rtol=0, atol=1e-11)
    tips = [
        plant.EvalBodyPoseInWorld(context, c)
        .inverse()
        .multiply(plant.EvalBodyPoseInWorld(context, r).translation())
        for c, r in zip(handles.cranks, handles.rods)
    ]
    np.testing.assert_allclose(
        np.array(tips), np.column_stack([geometry.crank_lengths, np.zeros((6, 2))]), atol=1e-12
    )


@pytest.fixture(scope="session", params=["symmetric", "drawn"])
def either_robot(request):
    """The drawing's robot, then a robot as built (:func:`drawn_robot`): for the checks that
    must hold on both."""
    return StewartGeometry() if request.param == "symmetric" else drawn_robot()


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


@pytest.fixture
def ctrl_c():
    """Python's own SIGINT handler, as in a user's terminal (a suite started in the background
    of a script inherits SIGINT ignored)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)


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
    from stewart_drake.control.lqi.controller import LqiController

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


#: The bound of every wait that guards against a hang, s: far beyond what anything a test waits
#: for takes on a machine loaded many times over (at a load of 20 on 2 cores a command's
#: start took minutes), so that only a hang reaches it. A wait bound below 1000 s in a test
#: is refused by tests/test_suite_rules.py unless its line says why it is kept.
HANG_S = 1800.0


def start_as_a_user(argv, cwd, **env) -> subprocess.Popen:
    """Start ``argv`` in ``cwd`` as a user's shell starts a command, the environment's variables
    and ``env`` set, streams piped as text: with SIGINT at its default, since a suite started
    in the background of a script inherits SIGINT ignored, and so would the command, which
    then never sees the Ctrl-C."""
    return subprocess.Popen(
        argv,
        cwd=cwd,
        env=dict(os.environ, **env),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )


def wait_for(condition, timeout_s: float, what: str, poll_s: float = 0.05):
    """Wait until ``condition()`` is true, polling every ``poll_s``; fail the test, naming
    ``what`` did not happen, after ``timeout_s``: a guard against a hang (:data:`HANG_S`),
    never a measure of speed. Returns the condition's last value."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"{what} did not happen within {timeout_s:g} s")
        time.sleep(poll_s)


def run_within(timeout_s: float, function, *args, what: str | None = None, **kwargs):
    """``function(*args, **kwargs)`` in a thread: its value, or the exception it raised; the
    test fails, saying what hung, if it has not ended after ``timeout_s`` (a guard against a
    hang, :data:`HANG_S`, never a measure of speed; the thread is left behind, a daemon)."""
    import threading

    outcome = {}

    def call():
        try:
            outcome["value"] = function(*args, **kwargs)
        except BaseException as err:  # re-raised in the test's thread
            outcome["error"] = err

    worker = threading.Thread(target=call, daemon=True)
    worker.start()
    worker.join(timeout_s)
    if worker.is_alive():
        pytest.fail(f"{what or getattr(function, '__name__', function)} hung for {timeout_s:g} s")
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("value")


# -- the robot's bus emulator in this process ---------------------------------------------------

#: The bus's settings of the robot's tests on the emulator: its pseudo-terminal passes bytes
#: through the kernel's tty workers, which a loaded machine (a load of 8 on 2 cores) delays by up
#: to a second each way, whatever the emulator does; the SDK's reply timeout (34 ms, a USB
#: adapter's latency timer) then reads as a servo that does not answer. What these tests check
#: is where a run ends and what it tracks, not how fast: a reply may take up to the bus's
#: largest timeout (5 s; a hang still fails), a command may come up to the servos' largest
#: watchdog (2.54 s) apart, and late periods are counted, not fatal.
LOADED_MACHINE_BUS = {"reply_timeout_s": 5.0, "watchdog_s": 2.54, "max_deadline_misses": 1_000_000}


def bus_emulator(
    x0, command_step_s: float, ids=(1, 2, 3, 4, 5, 6), surrogate=None, s0_m=0.0, models=None
):
    """The bus emulator (:class:`~stewart_drake.station.bus.emulator.BusEmulator`, not started)
    in this process: servos ``ids`` with the robot's plant behind them resting at pose ``x0``
    (rad, m), stepped at 2 ms (half the CPU of 1 ms: the loop and the plant share this
    process's GIL), on the commanded clock: the plant advances ``command_step_s`` (the loop's
    control period, s) at each torque command and not otherwise. On a loaded machine the loop
    runs late, and a plant on the wall clock would move on without it (a guard trip that is
    the machine's, not the robot's); on the commanded clock it meets the plant where its own
    clock says it is. With ``surrogate`` (a ``SurrogateServoConfig``) its stage
    answers as one more servo, its carriage at ``s0_m`` (m), on the same clock; ``models``:
    the emulator's {id: model}."""
    from pydrake.multibody.plant import MultibodyPlantConfig

    from stewart_drake.live.plant_backend import StationServos, dynamixel_scenario
    from stewart_drake.run.scenario import Scenario
    from stewart_drake.station.bus.emulator import BusEmulator
    from stewart_drake.station.bus.servo_models import FirstOrderServos, StackedServos

    robot = Scenario(
        plant=MultibodyPlantConfig(time_step=0.002, discrete_contact_approximation="sap"),
        control_period_s=0.002,
        log_period_s=0.002,
    )
    backend = StationServos(dynamixel_scenario(scenario=robot), x0=x0)
    ids, zero_counts = list(ids), None
    if surrogate is not None:
        stage = FirstOrderServos.linear_stage(surrogate.stage, surrogate.direction * s0_m)
        backend = StackedServos(backend, stage)
        zero_counts = [2048] * len(ids) + [surrogate.zero_counts]
        ids.append(surrogate.id)
    return BusEmulator(
        ids,
        backend=backend,
        command_step_s=command_step_s,
        zero_counts=zero_counts,
        models=models,
    )


def on_bus_read(n, action):
    """A session's ``before_torque`` hook: ``action()`` at the n-th bus read of the run."""

    def hook(sd, simulator):
        bus = sd.station.bus
        read = bus.read_state
        calls = [0]

        def counted():
            calls[0] += 1
            if calls[0] == n:
                action()
            return read()

        bus.read_state = counted

    return hook


def robot_bus_yaml(tmp_path) -> Path:
    """The shipped bus scenario (``robot``'s default) with :data:`LOADED_MACHINE_BUS`, written
    in ``tmp_path``; returns its path."""
    from stewart_drake.run.scenario import dump_scenario
    from stewart_drake.run.scenario_io import ROBOT_SCENARIO, load_scenario
    from stewart_drake.station.bus.servos import DynamixelBusConfig

    scenario = load_scenario(ROBOT_SCENARIO)
    scenario.bus = DynamixelBusConfig(**LOADED_MACHINE_BUS)
    path = tmp_path / "bus.yaml"
    path.write_text(dump_scenario(scenario))
    return path
