"""Example inputs to try the commands on (``stewart-drake examples [DIR]``): a tracker's marker
exports, a registration, the robot's encoder log, recorded traces and a depth camera's file,
shipped in ``stewart_drake/data/examples/`` and copied into a folder of the user's.

Every command block of README.md and docs/*.md runs as written in a folder holding them
(tests/test_docs_commands.py). They are small synthetic files, made by
``python tools/make_examples.py`` (seeded: the same files every time), which their README.md
describes: what each is, how it was made and what the commands show on it.

Nothing is overwritten that this command did not write: a file of an example's name is replaced
only when it is an example as shipped or the copy this command wrote there last (its SHA-256 is
kept in :data:`MANIFEST` in that folder), never a file of the user's or a copy they changed.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
from pathlib import Path

from ..base.errors import CorruptFileError, InvalidConfigError
from ..base.fileio import atomic_write, read_checked, read_json

#: The shipped examples: {file name: what it is and what a command shows on it}, in the order
#: the command writes them (tools/make_examples.py makes them and their README from this).
EXAMPLES = {
    "markers.csv": "a tracker's marker export (semicolons, decimal commas, ms, a frame column) "
    "of the library's breathing with a 2 deg tilt, 40 s at 100 Hz, 60 ms late, on the "
    "tracker's clock, the tracker's axes the base frame's: verify PASSes it",
    "markers_turned.csv": "the same run seen by a tracker 1 m and 30 deg from the base, the "
    "marker 50 mm off the platform: verify FAILs it as turned without --registration REG.yaml",
    "REG.yaml": "the fiducials that register markers_turned.csv's tracker to the robot "
    "(verify --registration, calibrate --registration)",
    "reg_markers.csv": "the library's registration motion seen by that tracker, 40 s at "
    "100 Hz: calibrate --register registers the tracker from it",
    "run_encoders.csv": "the robot's encoder log of the same breathing, 15 ms late, 17-bit "
    "encoders, as stewart-drake robot writes it, with a surrogate's carriage (s, s_cmd) "
    "following it through a correlation model: verify judges it beside the tracker's export, "
    "and with --surrogate model the pair",
    "trace.txt": "a recorded 6-D trace in the motion phantom's 7-column format (t LR SI AP "
    "rLR rSI rAP; s, mm, deg), 120 s of irregular breathing at 5 Hz: reproduce, check, "
    "--stream, --feedforward",
    "surrogate.txt": "the 2-column external surrogate recorded with trace.txt (t, chest "
    "displacement in mm, 5 Hz): the pair of an internal and an external motion",
    "depth.csv": "a depth camera's single axis (t [s],depth [mm]) of the phantom following "
    "trace.txt, on the camera's own clock, 5.45 s late, 0.6 mm of noise: verify judges it on AP",
    "depth_surrogate.csv": "the same camera's depth of the surrogate platform following "
    "surrogate.txt, on the same clock and in sync: verify trace.txt --surrogate surrogate.txt "
    "judges the pair and their relative latency",
    "patient.csv": "a recorded trace with a header naming each column and its unit "
    "(time [s],SI [mm],AP [mm],rot_LR [deg]), 20 s at 30 Hz: reproduce patient.csv",
    "ref.csv": "a reference of the project's own CSV (t,phi,theta,psi,X,Y,Z in s, rad, m), "
    "8 s at 50 Hz: run --trajectory-file ref.csv",
    "servo_bench.json": "a servo's bench log: an emulated XL330-M288-T swinging 0.49 kg at "
    "0.1 m in its own position mode, 6 s at 200 Hz: servo replay, servo identify",
}
#: What this command keeps in the folder it wrote to: the SHA-256 of each file it wrote there.
MANIFEST = ".stewart-drake-examples.json"
#: The largest example, bytes: a larger file of an example's name is not one of ours.
MAX_EXAMPLE_BYTES = 4e6
#: The examples' folder in the package.
FOLDER = Path(__file__).resolve().parents[1] / "data" / "examples"


def _sha256(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def _written_before(folder: Path) -> dict:
    """{name: SHA-256} of the files this command wrote into ``folder`` before (its
    :data:`MANIFEST`), or {} when it never wrote there.

    Raises:
        CorruptFileError: the manifest is not this command's JSON.
    """
    path = folder / MANIFEST
    if not os.path.lexists(path):
        return {}
    remedy = f"remove {path} and the examples it lists, or choose another folder"
    data = read_json(path, "examples manifest", remedy, max_bytes=1e5)
    files = data.get("files") if isinstance(data, dict) else None
    if not isinstance(files, dict) or not all(isinstance(v, str) for v in files.values()):
        raise CorruptFileError(path, "examples manifest", "it lists no files", remedy)
    return files


def _theirs(path: Path, shipped: bytes, written: str | None) -> bool:
    """Whether ``path`` holds something this command must not replace: anything but a regular
    file (a symlink, a folder, a FIFO) or a file whose bytes are neither the shipped example's
    nor what this command wrote there last."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return False
    if not stat.S_ISREG(mode):
        return True
    if os.stat(path).st_size > MAX_EXAMPLE_BYTES:
        return True
    digest = _sha256(read_checked(path, "example", MAX_EXAMPLE_BYTES))
    return digest not in (_sha256(shipped), written)


def copy_examples(folder) -> list[tuple[Path, int, str]]:
    """Copy the shipped examples (:data:`EXAMPLES`) into ``folder`` (made if missing), each
    written atomically, and record them in its :data:`MANIFEST`.

    Returns:
        (path, size in bytes, what it is) of each file written, in :data:`EXAMPLES`' order.
    Raises:
        InvalidConfigError: ``folder`` is not a folder, or holds a file of an example's name
            that this command did not write (a file of the user's, or a copy changed since):
            every such file named, nothing written.
        CorruptFileError: a shipped example or the folder's manifest cannot be read as one.
        OSError: a file cannot be read or written (permissions, a full disk).
    """
    folder = Path(folder)
    if os.path.lexists(folder) and not folder.is_dir():
        raise InvalidConfigError(f"{folder} is not a folder: give a folder to copy the examples to")
    shipped = {
        name: read_checked(
            FOLDER / name, "shipped example", MAX_EXAMPLE_BYTES, "reinstall stewart-drake"
        )
        for name in EXAMPLES
    }
    written = _written_before(folder) if folder.is_dir() else {}
    conflicts = [
        name for name, data in shipped.items() if _theirs(folder / name, data, written.get(name))
    ]
    if conflicts:
        names = ", ".join(str(folder / n) for n in conflicts)
        raise InvalidConfigError(
            f"{names}: not written by stewart-drake examples (or changed since), so not "
            f"replaced; move {'it' if len(conflicts) == 1 else 'them'} away or give another "
            f"folder (stewart-drake examples DIR); nothing was written"
        )
    folder.mkdir(parents=True, exist_ok=True)
    done = []
    for name, data in shipped.items():
        atomic_write(folder / name, lambda f, data=data: f.write(data))
        written[name] = _sha256(data)
        done.append((folder / name, len(data), EXAMPLES[name]))
    manifest = json.dumps({"written_by": "stewart-drake examples", "files": written}, indent=1)
    atomic_write(folder / MANIFEST, lambda f: f.write(manifest.encode() + b"\n"))
    return done
