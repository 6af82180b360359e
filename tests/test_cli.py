"""The command's habits: --version, every default in --help, the choices listed, a CSV reference
that sets the run's length, `workspace` on the scenario's robot."""

import argparse
import csv
import sys

import numpy as np
import pytest

from stewart_drake.cli import main as cli
from stewart_drake.cli.registry import build_parser
from stewart_drake.references.trajectories import TRAJECTORIES, paper_manoeuvre
from stewart_drake.run.result import load_result


def test_version_names_this_package_drake_and_python(capsys):
    """The versions as pyproject.toml and the installed Drake give them, not as written here."""
    import tomllib
    from importlib.metadata import version
    from pathlib import Path

    project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    with pytest.raises(SystemExit) as info:
        cli.main(["--version"])
    assert info.value.code == 0
    out = capsys.readouterr().out.strip()
    python = ".".join(map(str, sys.version_info[:3]))
    ours = project["project"]["version"]
    assert out == f"stewart-drake {ours} (drake {version('drake')}, Python {python})"


def _options():
    """(command, action) of every option of every subcommand."""
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    for name, command in sub.choices.items():
        for action in command._actions:
            if action.option_strings and not isinstance(action, argparse._HelpAction):
                yield name, command, action


def test_every_option_shows_its_default_in_help():
    missing = []
    for name, command, action in _options():
        if isinstance(action, argparse._StoreTrueAction):
            continue  # a flag: off unless given
        if action.help == argparse.SUPPRESS:
            continue  # an option that only says where it moved: no help shown
        text = command.formatter_class("x")._get_help_string(action) % {"default": action.default}
        if "default" not in text:
            missing.append(f"{name} {action.option_strings[0]}")
    assert not missing, f"options whose help does not say their default: {missing}"
    help_text = build_parser()._subparsers._group_actions[0].choices["run"].format_help()
    assert "(default: results)" in help_text and "(default: paper_hardware)" in help_text


@pytest.mark.parametrize(
    "argv, expected",
    [
        (
            ["check", "--trajectory-file", "x.csv"],
            "stewart-drake check: error: unrecognized "
            "arguments: --trajectory-file (see stewart-drake check --help)",
        ),
        (
            ["run", "extra"],
            "stewart-drake run: error: unrecognized arguments: extra (see "
            "stewart-drake run --help)",
        ),
    ],
)
def test_an_option_a_command_does_not_take_is_refused_by_that_command(argv, expected, capsys):
    """The refusal names the command and the help that lists its options, not the top one's."""
    with pytest.raises(SystemExit) as info:
        cli.main(argv)
    assert info.value.code == 2
    assert capsys.readouterr().err.strip() == expected


def test_trajectory_lists_its_choices():
    (action,) = [
        a for name, _, a in _options() if name == "run" and "--trajectory" in a.option_strings
    ]
    assert list(action.choices) == sorted(TRAJECTORIES)
    assert all(name in action.help for name in TRAJECTORIES)


def _write_csv(path, duration_s, period_s=0.01):
    t = np.arange(0.0, duration_s + period_s / 2, period_s)
    pose = paper_manoeuvre().evaluate(t)[0]
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["t", "phi", "theta", "psi", "X", "Y", "Z"])
        writer.writerows(np.column_stack([t, pose]).tolist())
    return path


def test_a_csv_reference_sets_the_run_to_its_own_length(tmp_path, capsys):
    """Shorter than the scenario's 10 s: the run lasts as long as the file (it was refused);
    --duration still cuts it."""
    ref = _write_csv(tmp_path / "short.csv", 0.24)
    assert (
        cli.main(
            ["run", "--trajectory-file", str(ref), "--out", str(tmp_path / "a"), "--no-progress"]
        )
        == 0
    )
    result = load_result(tmp_path / "a" / "run_short.npz")
    assert result.t[-1] == pytest.approx(0.24) and result.config_summary["duration_s"] == 0.24
    run_ref = ["run", "--trajectory-file", str(ref), "--no-progress"]
    assert cli.main(run_ref + ["--duration", "0.1", "--out", str(tmp_path / "b")]) == 0
    assert load_result(tmp_path / "b" / "run_short.npz").t[-1] == pytest.approx(0.1)
    capsys.readouterr()
    assert cli.main(run_ref + ["--duration", "0.5", "--out", str(tmp_path / "c")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1  # longer than the file


def test_workspace_sweeps_the_scenario_s_robot(tmp_path, capsys):
    """--scenario and --set as for `run`: a longer rod reaches higher."""

    def volume(out, *extra):
        assert (
            cli.main(
                [
                    "workspace",
                    "--resolution",
                    "5",
                    "--runner",
                    "serial",
                    "--out",
                    str(tmp_path / out),
                    "--no-progress",
                    *extra,
                ]
            )
            == 0
        )
        rows = {
            r[0]: float(r[1])
            for r in csv.reader(open(tmp_path / out / "summary.csv"))
            if r[0] != "figure"
        }
        return rows["reachable_volume"]

    assert volume("long", "--set", "robot.rod_length=0.45") > 1.5 * volume("default")
    # A grid this coarse says so: its extents are known to within a quarter of the box.
    assert "--resolution 5 is coarse: each extent is known only to within a step of 1/4" in (
        capsys.readouterr().err
    )
    assert (
        cli.main(
            [
                "workspace",
                "--set",
                "robot.rod_length=-1",
                "--out",
                str(tmp_path / "bad"),
                "--no-progress",
            ]
        )
        == 2
    )
    assert "rod_length" in capsys.readouterr().err
