"""``stewart-drake examples``: the shipped example inputs copied into a folder, only the
command's own files ever replaced; and the shipped files are what tools/make_examples.py makes."""

import hashlib
import importlib.util
import json
from pathlib import Path

import pytest

from stewart_drake.cli.main import main
from stewart_drake.organ_motion.examples import EXAMPLES, FOLDER, MANIFEST

REPO = Path(__file__).resolve().parent.parent
_SPEC = importlib.util.spec_from_file_location("make_examples", REPO / "tools" / "make_examples.py")
make_examples = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(make_examples)


def test_the_examples_are_copied_each_named_and_described(tmp_path, capsys):
    target = tmp_path / "new" / "folder"
    assert main(["examples", str(target)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert [line.split(" ")[1] for line in out] == [str(target / n) for n in EXAMPLES]
    for name in EXAMPLES:
        assert (target / name).read_bytes() == (FOLDER / name).read_bytes()
    assert "markers.csv (175 kB): a tracker's marker export" in out[0]
    manifest = json.loads((target / MANIFEST).read_text())
    assert set(manifest["files"]) == set(EXAMPLES)


def test_the_default_folder_is_the_current_one(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["examples"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*EXAMPLES, MANIFEST])
    assert capsys.readouterr().out.startswith("wrote markers.csv (")


def test_its_own_files_are_replaced_a_users_never(tmp_path, capsys):
    assert main(["examples", str(tmp_path)]) == 0
    # Its own copies, and a copy it wrote from an earlier version (the manifest's digest), are
    # replaced by the shipped examples.
    (tmp_path / "trace.txt").write_text("0 0 0 0 0 0 0\n")
    manifest = json.loads((tmp_path / MANIFEST).read_text())
    manifest["files"]["trace.txt"] = hashlib.sha256(b"0 0 0 0 0 0 0\n").hexdigest()
    (tmp_path / MANIFEST).write_text(json.dumps(manifest))
    assert main(["examples", str(tmp_path)]) == 0
    assert (tmp_path / "trace.txt").read_bytes() == (FOLDER / "trace.txt").read_bytes()
    capsys.readouterr()
    # A user's file of an example's name, and a copy the user changed: refused, both named,
    # nothing written.
    (tmp_path / "patient.csv").write_text("time [s],SI [mm]\n0,1\n")
    (tmp_path / "ref.csv").write_bytes((FOLDER / "ref.csv").read_bytes() + b"\n")
    (tmp_path / "markers.csv").unlink()
    assert main(["examples", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("stewart-drake examples: ")
    assert f"{tmp_path / 'patient.csv'}, {tmp_path / 'ref.csv'}: not written by" in err
    assert "nothing was written" in err and not (tmp_path / "markers.csv").exists()
    assert (tmp_path / "patient.csv").read_text() == "time [s],SI [mm]\n0,1\n"


@pytest.mark.parametrize("what", ["folder", "symlink", "not a folder", "manifest"])
def test_what_is_not_a_file_of_its_own_is_refused(tmp_path, capsys, what):
    target = tmp_path / "ex"
    target.mkdir()
    if what == "folder":
        (target / "REG.yaml").mkdir()
    elif what == "symlink":
        (tmp_path / "mine.txt").write_bytes((FOLDER / "trace.txt").read_bytes())
        (target / "trace.txt").symlink_to(tmp_path / "mine.txt")
    elif what == "not a folder":
        target.rmdir()
        target.write_text("x")
    else:
        (target / MANIFEST).write_text("[1, 2]")
    assert main(["examples", str(target)]) == 2
    err = capsys.readouterr().err
    expected = {
        "folder": "REG.yaml: not written by stewart-drake examples",
        "symlink": "trace.txt: not written by stewart-drake examples",
        "not a folder": "is not a folder",
        "manifest": "it lists no files",
    }[what]
    assert expected in err
    if what == "symlink":
        assert (tmp_path / "mine.txt").read_bytes() == (FOLDER / "trace.txt").read_bytes()


def test_the_shipped_examples_are_what_the_tool_makes(tmp_path, capsys):
    """tools/make_examples.py --check: the files and their README as the tool writes them (its
    numbers to 1e-9: another numpy may round a last digit otherwise); and the check can fail."""
    assert make_examples.main(["--check"]) == 0, capsys.readouterr().out
    make_examples.make(tmp_path)
    (tmp_path / "patient.csv").write_text(
        (tmp_path / "patient.csv").read_text().replace("7.50", "7.51", 1)
    )
    (tmp_path / "README.md").write_text("other\n")
    assert make_examples.differences(FOLDER, tmp_path) == [
        "README.md: its text differs",
        "patient.csv: 1 numbers differ",
    ]
    assert sorted(p.name for p in FOLDER.iterdir()) == sorted([*EXAMPLES, "README.md"])
    assert all((FOLDER / n).stat().st_size < 300e3 for n in EXAMPLES)
