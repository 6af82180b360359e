"""The command sizes glibc's thread cache for itself once, and keeps the user's choice."""

import os
import subprocess
import sys

import pytest

from stewart_drake.base.allocator import (
    TCACHE_COUNT,
    TCACHE_TUNABLE,
    is_glibc,
    tuned_environment,
)

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
    done = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return seen.read_text().splitlines(), done.stdout


def test_the_command_starts_itself_again_once_with_the_cache_sized(tmp_path):
    seen, out = _started([sys.executable, "-m", "stewart_drake.cli.main", "--help"], tmp_path)
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
