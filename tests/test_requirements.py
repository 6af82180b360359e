"""A design task as a file: the shipped acceptance set loads with its numbers, and each bad file is
refused with one typed line naming the file and the field."""

from pathlib import Path

import numpy as np
import pytest

from stewart_drake.base.errors import CorruptFileError, InvalidConfigError, MissingFileError
from stewart_drake.design.requirements import DesignRequirements, load_requirements
from stewart_drake.references.organ.library import OrganMotionReference
from stewart_drake.references.trajectories import NamedReference

SHIPPED = Path(__file__).resolve().parent.parent / "scenarios" / "design_requirements.yaml"


def test_the_acceptance_set_loads_with_its_numbers():
    r = load_requirements(SHIPPED)
    paper, organs = r.motions
    assert isinstance(paper, NamedReference) and paper.name == "paper"
    assert isinstance(organs, OrganMotionReference) and organs.motion == "breathing_heartbeat"
    # The organ motion as the library builds it: 15 mm peak to peak breathing plus 2 mm heart.
    x = organs.make(None, 8.0, None).evaluate(np.linspace(0.0, 8.0, 8001))[0]
    assert np.ptp(x[:, 3]) == pytest.approx(0.015, rel=1e-3)  # SI is the pose's X
    assert np.ptp(x[:, 4]) == pytest.approx(0.002, rel=1e-2)  # LR is Y
    np.testing.assert_allclose(r.workspace.box_m, [0.03, 0.03, 0.02])
    assert r.workspace.tilt_deg == 15.0
    np.testing.assert_allclose(r.workspace.centre_m, [0.0, 0.0, 0.30])  # the home height
    assert r.payload_kg == 0.5
    assert (r.margins.torque, r.margins.speed) == (0.1, 0.1)
    assert (r.resolution.translation_m, r.resolution.rotation_rad) == (5.0e-5, 5.0e-4)


@pytest.mark.parametrize(
    "text, error, message",
    [
        ("payload_kg: 50\n", InvalidConfigError, r"payload_kg must be .*20"),
        (
            "motions:\n  - !OrganMotionReference {motion: hiccup}\n",
            InvalidConfigError,
            r"motions\[0\]: .*hiccup",
        ),
        ("workspace: {box_m: [0.03, 0.03]}\n", InvalidConfigError, r"workspace\.box_m must be 3"),
        ("margins: {torque: 0.1, sped: 0.1}\n", CorruptFileError, r"sped"),
        (
            "resolution: {translation_m: 0.0, rotation_rad: 5.0e-4}\n",
            InvalidConfigError,
            r"resolution\.translation_m must be",
        ),
        (
            "accuracy: {translation_m: 5.0e-324}\n",
            InvalidConfigError,
            r"accuracy\.translation_m must be .*1e-07",
        ),
        (
            "resolution: {rotation_rad: 9.9e-8}\n",
            InvalidConfigError,
            r"resolution\.rotation_rad must be .*1e-07",
        ),
        ("payload_kg: [0.5\n", CorruptFileError, r"not YAML"),
        ("payload_kg: 0.5\npayload_kg: 0.6\n", InvalidConfigError, r"'payload_kg' appears twice"),
        (
            "motions:\n  - !TraceReference {path: nowhere.csv}\n",
            MissingFileError,
            r"motions\[0\]: .*nowhere\.csv",
        ),
        ("motions: []\n", InvalidConfigError, r"at least one motion or a workspace"),
    ],
)
def test_bad_files_are_one_typed_line_naming_the_file_and_field(tmp_path, text, error, message):
    path = tmp_path / "task.yaml"
    path.write_text(text)
    with pytest.raises(error, match=message) as caught:
        load_requirements(path)
    assert "\n" not in str(caught.value)
    assert str(path) in str(caught.value)


def test_missing_and_empty_files_are_refused(tmp_path):
    with pytest.raises(MissingFileError, match="no design requirements file"):
        load_requirements(tmp_path / "nowhere.yaml")
    (tmp_path / "empty.yaml").write_text("\n")
    with pytest.raises(CorruptFileError, match="it is empty"):
        load_requirements(tmp_path / "empty.yaml")


def test_the_defaults_are_the_paper_manoeuvre_and_the_guards_margin():
    r = DesignRequirements().validate()
    assert r.motions == [NamedReference(name="paper")]
    assert r.workspace is None and r.payload_kg == 0.0
    assert r.margins.torque == pytest.approx(0.1)


def test_a_requirements_file_is_not_a_shipped_scenario():
    from stewart_drake.run.scenario_io import shipped_scenarios

    assert SHIPPED.exists() and "design_requirements" not in shipped_scenarios()


def test_the_finest_requirements_are_taken():
    from stewart_drake.design.requirements import Accuracy, Resolution

    Accuracy(translation_m=1e-7, rotation_rad=1e-7).validate()
    Resolution(translation_m=1e-7, rotation_rad=1e-7).validate()
