"""The result store: a folder of another command or an older layout is refused by name."""

import json

import pytest

from stewart_drake.base.errors import ResultsMismatchError


def test_a_folder_of_another_command_or_an_older_layout_is_refused_by_name(tmp_path):
    from stewart_drake.execution.store import ResultStore

    ResultStore(tmp_path / "c", "collect", {"seed": 0}, pattern="run_*.npz")
    with pytest.raises(
        ResultsMismatchError, match="holds results of `stewart-drake collect`, not of `evaluate`"
    ):
        ResultStore(tmp_path / "c", "evaluate", {"quick": True}, pattern="rows/*.json")
    old = tmp_path / "old"
    old.mkdir()
    (old / "manifest.json").write_text(json.dumps({"seed": 0, "runs": []}))  # an older format
    with pytest.raises(ResultsMismatchError, match="results of an older stewart-drake"):
        ResultStore(old, "collect", {"seed": 0}, pattern="run_*.npz")
    (tmp_path / "bare").mkdir()
    (tmp_path / "bare" / "run_0.npz").write_bytes(b"PK")
    with pytest.raises(ResultsMismatchError, match="run_\\*.npz files without a manifest.json"):
        ResultStore(tmp_path / "bare", "collect", {"seed": 0}, pattern="run_*.npz")
