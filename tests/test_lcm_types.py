"""The LCM message types: the committed Python is what lcm-gen makes of the committed ``.lcm``
files, imports only the standard library, lays the fields out on the wire as LCM specifies, and
round-trips through Drake's LCM in process (``memq://``: no network, no multicast)."""

import ast
import pathlib
import shutil
import struct
import subprocess
import sys

import pytest
from pydrake.lcm import DrakeLcm

from stewart_drake.lcmtypes import (
    lcmt_stewart_command,
    lcmt_stewart_pose_sample,
    lcmt_stewart_status,
)

TYPES = pathlib.Path(__file__).resolve().parent.parent / "stewart_drake" / "lcmtypes"
#: The lcm-gen the committed files come from (the ``test`` extra pins ``lcm`` to it).
LCM_GEN_VERSION = "1.5.3"


def lcm_gen() -> str:
    """The path of lcm-gen (on PATH or beside this interpreter, where the lcm wheel puts it), or
    skip."""
    found = shutil.which("lcm-gen") or shutil.which(
        "lcm-gen", path=str(pathlib.Path(sys.executable).parent)
    )
    if found is None:
        pytest.skip("lcm-gen not found (pip install lcm, part of the test extra)")
    return found


def test_the_committed_types_are_what_lcm_gen_makes_of_the_definitions(tmp_path):
    tool = lcm_gen()
    version = subprocess.run([tool, "--version"], capture_output=True, text=True, check=True)
    if LCM_GEN_VERSION not in version.stdout:
        pytest.skip(
            f"{version.stdout.strip()} is not lcm-gen {LCM_GEN_VERSION}, which made the committed "
            f"types (pip install lcm=={LCM_GEN_VERSION})"
        )
    definitions = sorted(TYPES.glob("*.lcm"))
    assert [p.stem for p in definitions] == [
        "lcmt_stewart_command",
        "lcmt_stewart_pose_sample",
        "lcmt_stewart_status",
    ]
    # The command docs/lcm.md gives, run at the repository's top, into a scratch folder.
    subprocess.run(
        [tool, "--python", "--python-no-init", "--ppath", str(tmp_path)]
        + [str(p.relative_to(TYPES.parent.parent)) for p in definitions],
        cwd=TYPES.parent.parent,
        check=True,
    )
    generated = sorted((tmp_path / "stewart_drake" / "lcmtypes").iterdir())
    assert [p.name for p in generated] == [f"{p.stem}.py" for p in definitions]
    for path in generated:
        assert path.read_bytes() == (TYPES / path.name).read_bytes(), (
            f"stewart_drake/lcmtypes/{path.name} differs from lcm-gen's output: regenerate it "
            "(docs/lcm.md)"
        )
    # Nothing else written: --python-no-init leaves our __init__.py (and stewart_drake's) alone.
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*")) == [
        "stewart_drake",
        "stewart_drake/lcmtypes",
    ] + [f"stewart_drake/lcmtypes/{p.name}" for p in generated]


def test_the_generated_types_import_only_the_standard_library():
    imported = set()
    for path in TYPES.glob("lcmt_*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                imported |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{path.name} imports relatively"
                imported.add(node.module.split(".")[0])
    assert imported and imported <= sys.stdlib_module_names, imported - sys.stdlib_module_names


def a_status() -> lcmt_stewart_status:
    message = lcmt_stewart_status()
    message.utime = 1_234_567_890_123
    message.theta = [0.1 * i - 0.2 for i in range(6)]
    message.theta_dot = [-1.5 + i for i in range(6)]
    message.tau = [0.702, -0.702, 0.0, 1e-9, -3.25, 0.5]
    message.x = [0.01, -0.02, 0.03, 0.004, -0.005, 0.30]
    message.x_d = [0.0, 0.0, 0.05, 0.0, 0.0, 0.31]
    message.mode = lcmt_stewart_status.MODE_STOPPED
    message.reason = "guard: motor 2 at 0.71 N m > 0.702 N m (°)"
    message.deadline_misses = 3
    message.period_us = 1_012
    message.measurement_age_us = -7
    return message


FIELDS = lcmt_stewart_status.__slots__


def test_the_status_is_laid_out_on_the_wire_as_lcm_specifies():
    # LCM: an 8-byte fingerprint, then the fields in order, big-endian, arrays inline, a string
    # as its length with the terminating NUL, the bytes and the NUL.
    message = a_status()
    data = message.encode()
    reason = message.reason.encode("utf-8")
    assert len(data) == 8 + 8 + 5 * 6 * 8 + 1 + 4 + len(reason) + 1 + 3 * 4
    assert data[:8] == struct.pack(">Q", message.get_hash())
    (t,) = struct.unpack_from(">q", data, 8)
    arrays = struct.unpack_from(">30d", data, 16)
    assert t == message.utime
    assert list(arrays) == message.theta + message.theta_dot + message.tau + message.x + message.x_d
    offset = 16 + 240
    (mode, size) = struct.unpack_from(">bI", data, offset)
    assert (mode, size) == (3, len(reason) + 1)
    assert data[offset + 5 : offset + 5 + size] == reason + b"\0"
    assert struct.unpack_from(">3i", data, offset + 5 + size) == (3, 1012, -7)
    # The types differ, and so do their fingerprints: a reader refuses the other's bytes.
    with pytest.raises(ValueError, match="Decode error"):
        lcmt_stewart_command.decode(data)


def test_status_and_command_round_trip_through_drake_lcm_in_process():
    lcm = DrakeLcm("memq://")
    received = {"STEWART_STATUS": [], "STEWART_COMMAND": []}
    for channel, messages in received.items():
        lcm.Subscribe(channel, messages.append)
    status = a_status()
    command = lcmt_stewart_command()
    command.utime, command.tau = 42, [0.5, -0.25, 0.125, 0.0, -1.0, 2.0]
    lcm.Publish("STEWART_STATUS", status.encode())
    lcm.Publish("STEWART_COMMAND", command.encode())
    for _ in range(10):  # bounded: memq delivers what is queued at once
        if all(received.values()):
            break
        lcm.HandleSubscriptions(10)
    assert [len(m) for m in received.values()] == [1, 1]
    back = lcmt_stewart_status.decode(received["STEWART_STATUS"][0])
    for name in FIELDS:
        sent, got = getattr(status, name), getattr(back, name)
        assert (list(got) if isinstance(sent, list) else got) == sent, name
    back_command = lcmt_stewart_command.decode(received["STEWART_COMMAND"][0])
    assert (back_command.utime, list(back_command.tau)) == (42, command.tau)


def test_a_pose_sample_is_laid_out_on_the_wire_and_refused_as_another_type():
    sample = lcmt_stewart_pose_sample()
    sample.utime, sample.seq = -5_000_000, 2**40 + 3
    sample.pose = [0.01, -0.02, 0.03, 0.004, -0.005, 0.30]
    data = sample.encode()
    assert len(data) == 8 + 8 + 8 + 6 * 8
    assert data[:8] == struct.pack(">Q", sample.get_hash())
    assert struct.unpack_from(">qq6d", data, 8) == (sample.utime, sample.seq, *sample.pose)
    back = lcmt_stewart_pose_sample.decode(data)
    assert (back.utime, back.seq, list(back.pose)) == (sample.utime, sample.seq, sample.pose)
    with pytest.raises(ValueError, match="Decode error"):
        lcmt_stewart_status.decode(data)
