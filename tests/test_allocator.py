"""The command sizes glibc's thread cache for itself once, and keeps the user's choice."""

import os
import subprocess
import sys

import pytest
from conftest import HANG_S

from stewart_drake.base.allocator import (
    TCACHE_COUNT,
    TCACHE_TUNABLE,
    is_glibc,
    tuned_environment,
)
from stewart_drake.execution.options import STARTING

pytestmark = pytest.mark.skipif(not is_glibc(), reason="glibc's tunables only")

OURS = f"{TCACHE_TUNABLE}={TCACHE_COUNT}"


def test_the_tunable_is_added_to_an_environment_without_one():
    env = tuned_environment({"HOME": "/h"})
    assert env == {"HOME": "/h", "GLIBC_TUNABLES": OURS}


def test_other_tunables_are_kept_and_the_users_cache_size_stands():
    env = tuned_environment({"GLIBC_TUNABLES": "glibc.malloc.trim_threshold=1"})
    assert env["GLIBC_TUNABLES"] == f"glibc.malloc.trim_threshold=1:{OURS}"
    assert tuned_environment({"GLIBC_TUNABLES": f"a=1:{TCACHE_TUNABLE}=7"}) is None
    # A longer tunable's name that starts with ours is not ours.
    longer = {"GLIBC_TUNABLES": f"{TCACHE_TUNABLE}_x=1"}
    assert tuned_environment(longer)["GLIBC_TUNABLES"] == f"{TCACHE_TUNABLE}_x=1:{OURS}"


def _started(argv, tmp_path, tunables=None):
    """What each interpreter start of ``argv`` saw in GLIBC_TUNABLES (a sitecustomize on the
    path writes it down at every start, before any of the package runs)."""
    seen = tmp_path / "seen.txt"
    (tmp_path / "sitecustomize.py").write_text(
        "import os\n"
        f"with open({str(seen)!r}, 'a') as f:\n"
        "    f.write(repr(os.environ.get('GLIBC_TUNABLES')) + '\\n')\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"}
    if tunables is not None:
        env["GLIBC_TUNABLES"] = tunables
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tmp_path), env.get("PYTHONPATH")]))
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=HANG_S)
    assert done.returncode == 0, done.stderr
    return seen.read_text().splitlines(), done.stdout


@pytest.mark.parametrize("module", ["stewart_drake.cli.main", "stewart_drake"])
def test_the_command_starts_itself_again_once_with_the_cache_sized(tmp_path, module):
    seen, out = _started([sys.executable, "-m", module, "--help"], tmp_path)
    assert seen == ["None", repr(OURS)]
    assert "usage: stewart-drake" in out


def test_the_command_keeps_the_users_setting_and_starts_once(tmp_path):
    mine = f"{TCACHE_TUNABLE}=7"
    seen, _ = _started(
        [sys.executable, "-m", "stewart_drake.cli.main", "--help"], tmp_path, tunables=mine
    )
    assert seen == [repr(mine)]


def test_a_library_user_is_never_restarted(tmp_path):
    seen, out = _started(
        [sys.executable, "-c", "import stewart_drake.cli.main; print('ran once')"], tmp_path
    )
    assert seen == ["None"]
    assert out.splitlines() == ["ran once"]


# -- where starting again would not run the same command: it runs as it is, and says so ---------

_SCRIPT = os.path.join(os.path.dirname(sys.executable), "stewart-drake")
_AS_IS = "stewart-drake: runs with glibc's default memory cache ("


def _run_with_probe(argv, tmp_path, **kwargs):
    """(starts seen, exit code, stdout, stderr) of ``argv`` with the start probe of
    :func:`_started`, the streams as ``kwargs`` give them."""
    seen = tmp_path / "seen.txt"
    (tmp_path / "sitecustomize.py").write_text(
        f"with open({str(seen)!r}, 'a') as f:\n    f.write('start\\n')\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tmp_path), env.get("PYTHONPATH")]))
    done = subprocess.run(argv, env=env, capture_output=True, timeout=HANG_S, **kwargs)
    starts = seen.read_text().splitlines() if seen.exists() else []
    return len(starts), done.returncode, done.stdout.decode(), done.stderr.decode()


def test_with_standard_output_closed_the_command_runs_once_as_it_is(tmp_path):
    """Was: an AttributeError traceback from the restart's flush of a stream Python has not."""
    argv = [_SCRIPT, "scenario", "nope"]
    starts, code, _, err = _run_with_probe(
        ["sh", "-c", 'exec "$0" "$@" >&-', *argv], tmp_path, stdout=None
    )
    assert (starts, code) == (1, 2), err
    assert "Traceback" not in err and "AttributeError" not in err
    lines = err.strip().splitlines()
    assert lines[0].startswith(_AS_IS + "its standard output is closed;"), lines
    assert lines[1] == f"stewart-drake scenario: {STARTING}", lines
    assert lines[2].startswith("stewart-drake scenario: no scenario file nope"), lines


def test_a_script_read_from_standard_input_is_not_started_again_with_it_consumed(tmp_path):
    """Was: ``python - < script`` started again with nothing left to read, and exit 0 having
    done nothing."""
    script = "import sys\nsys.argv = ['stewart-drake', '--version']\nimport stewart_drake\n"
    script += "print('the script ran')\n"
    starts, code, out, err = _run_with_probe([sys.executable, "-"], tmp_path, input=script.encode())
    assert (starts, code) == (1, 0) and out.strip() == "the script ran", (out, err)
    assert err.startswith(_AS_IS + "it was not started from its own script file;"), err


def test_a_link_to_the_command_is_the_command(tmp_path):
    """Was: a link of another name was taken for a library user: no restart, and no start-up
    Ctrl-C handler."""
    link = tmp_path / "sd"
    link.symlink_to(_SCRIPT)
    starts, code, out, _ = _run_with_probe([str(link), "--version"], tmp_path)
    assert (starts, code) == (2, 0) and out.startswith("stewart-drake ")


def test_a_ctrl_c_in_the_restart_s_window_is_one_line_and_130(tmp_path, ctrl_c):
    """A SIGINT that arrives while the command starts itself again (here, sent by the new
    interpreter to itself as its site customisation runs, before any of the package has) is
    held across the restart and answered by the command's start-up handler. Was: Python's
    KeyboardInterrupt traceback and exit 1."""
    (tmp_path / "sitecustomize.py").write_text(
        "import os, signal\n"
        f"if {TCACHE_TUNABLE!r} in os.environ.get('GLIBC_TUNABLES', ''):\n"
        "    os.kill(os.getpid(), signal.SIGINT)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tmp_path), env.get("PYTHONPATH")]))
    done = subprocess.run(
        [_SCRIPT, "--version"], env=env, capture_output=True, text=True, timeout=HANG_S
    )
    assert "Traceback" not in done.stderr, done.stderr
    assert done.returncode == 130 and done.stdout == "", (done.returncode, done.stdout)
    assert done.stderr.strip().splitlines() == [
        "stewart-drake: interrupted by SIGINT; partial outputs were not written"
    ]


def test_the_command_started_again_does_not_keep_ctrl_c_held(tmp_path):
    """The restart holds SIGINT only across its own exec: once the package is imported in the
    new process, SIGINT is unblocked (or every later Ctrl-C, and every process the command
    starts, would have it held)."""
    probe = (
        "import os, signal\n"
        "import stewart_drake\n"
        "held = signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, [])\n"
        "print(os.environ.get('GLIBC_TUNABLES'), held)\n"
    )
    script = tmp_path / "stewart-drake"
    script.write_text(probe)
    done = subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=HANG_S,
        env={k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"},
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [f"{OURS} False"], (done.stdout, done.stderr)
