"""Where a maintainer adds a thing (docs/development.md, "Where a maintainer adds a thing"):
each test adds a small one at the one place named there and sees it reach the command line, in
process, through the command a user types; none replaces the code it extends."""

import numpy as np

from stewart_drake.cli.main import main
from stewart_drake.references.organ.library import make_motion
from stewart_drake.verification import causes

#: The measured motion: the library's breathing, played 1.5 times too large by a phantom whose
#: tracker's axes are the base frame's (its offsets removed), 20 ms late.
BREATHING = make_motion("breathing", {})
SCALE, LATENCY_S = 1.5, 0.020


def _measured_file(path):
    t = np.arange(0.0, 30.0, 0.01)
    x = BREATHING.evaluate(t - LATENCY_S)[0]
    centre = x.mean(axis=0)
    x = centre + SCALE * (x - centre)
    rows = [f"{ti:.3f},{1e3 * p[3]:.5f},{1e3 * p[4]:.5f},{1e3 * p[5]:.5f}" for ti, p in zip(t, x)]
    path.write_text("t [s],X [mm],Y [mm],Z [mm]\n" + "\n".join(rows) + "\n")
    return path


def _verify(tmp_path, capsys) -> tuple[int, str]:
    measured = _measured_file(tmp_path / "measured.csv")
    code = main(["verify", "breathing", "--measured", str(measured), "--out", str(tmp_path / "o")])
    return code, capsys.readouterr().out


def test_a_verdict_criterion_added_to_the_one_list_reaches_verify(tmp_path, capsys, monkeypatch):
    """A criterion appended to ``causes.CRITERIA`` (an axis moving more than 1.2 times the
    reference's amplitude) is tried on every moving axis of a FAIL and its words, the
    criterion's own (no place has words for it), are on verify's verdict line; without it the
    same run names the amplitude through the stock words and not the new criterion."""
    (tmp_path / "without").mkdir()
    code, out = _verify(tmp_path / "without", capsys)
    assert code == 2 and "FAIL" in out
    assert "1.5x the reference's amplitude" in out
    assert "fails too large" not in out
    too_large = causes.Criterion(
        "too large",
        "its gain on the reference",
        "above 1.2",
        lambda case: () if case.fk["gain"] > 1.2 else None,
    )
    monkeypatch.setattr(causes, "CRITERIA", [*causes.CRITERIA, too_large])
    (tmp_path / "with").mkdir()
    code, out = _verify(tmp_path / "with", capsys)
    assert code == 2
    assert "fails too large (its gain on the reference: above 1.2)" in out
    # The new criterion comes after the stock ones: the amplitude's stock words give way to it.
    assert "1.5x the reference's amplitude" not in out


def test_a_servo_model_added_to_its_two_tables_reaches_a_command(tmp_path, capsys, monkeypatch):
    """A servo model is a row in the motor catalogue (its datasheet's torque, speed, gear,
    rotor, mass, price: ``robot.motor_catalogue.MOTOR_CATALOGUE``) and a row in the bus's models
    (its control table's units and limits: ``station.bus.servos.SERVO_SPECS``, its encoder's
    counts read from the first). A made-up X servo of 5.0 N m stall torque at 2.3 A and 60 rpm
    at no load, added to both, is what ``check paper_bus --set bus.model=...`` holds the
    reference to: the torque the scenario's Current Limit lets it give, K_t = 5.0 / 2.3 N m/A
    times the scenario's current_limit_A (under its 5.0 N m stall), and 60 rpm = 2 pi rad/s;
    the shipped XM430's 3.57 N m and 4.82 rad/s are gone."""
    from stewart_drake.robot import motor_catalogue
    from stewart_drake.run.scenario_io import load_scenario
    from stewart_drake.station.bus import servos

    name = "XM430-EXAMPLE-T"
    motor = motor_catalogue._dynamixel(name, 5.0, 60.0, 353.5, 1.0, 82.0, 300.0)
    monkeypatch.setitem(motor_catalogue.MOTOR_CATALOGUE, name, motor)
    monkeypatch.setitem(servos.SERVO_SPECS, name, servos._x_spec(name, 1020, 2.69e-3, 1193, 2.3))
    code = main(["check", "paper_bus", "--set", f"bus.model={name}", "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    current_limit_A = load_scenario("paper_bus").bus.current_limit_A
    peak, speed = min(5.0, 5.0 / 2.3 * current_limit_A), 2 * np.pi
    assert f"limit {0.9 * peak:.3g} N m, 90 % of the motors' {peak:.3g} N m peak" in out
    assert f"limit {0.9 * speed:.3g} rad/s, 90 % of the motors' {speed:.3g} rad/s no-load" in out
    assert "3.57 N m peak" not in out and "4.82 rad/s" not in out


def test_a_headerless_format_added_to_its_table_reaches_the_commands(tmp_path, capsys, monkeypatch):
    """A tracker's export without a header line, 4 columns (time s, then SI, LR, AP in mm), is
    a row of ``base.trace_layouts.HEADERLESS_FORMATS``. Added there, ``check FILE --format
    tracker4`` reads the file by the row's columns (200 samples at 10 Hz, SI on +X, AP on +Z),
    and ``check FILE`` alone knows it by its width; without the row the same file is refused,
    and ``--format tracker4`` is not a choice."""
    from stewart_drake.base import trace_layouts

    t = np.arange(0.0, 20.0, 0.1)
    rows = [
        f"{a:.2f} {5 * np.sin(np.pi * a / 2):.4f} 0.0 {2 * np.sin(np.pi * a / 2):.4f}" for a in t
    ]
    trace = tmp_path / "tracker.txt"
    trace.write_text("\n".join(rows) + "\n")
    argv = ["check", str(trace), "--out", str(tmp_path / "o")]

    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "no header line and 4 columns" in err
    assert "phantom: 7 columns" in err and "surrogate: 2 columns" in err
    try:
        main([*argv, "--format", "tracker4"])
    except SystemExit as end:  # argparse refuses a choice it does not have
        assert end.code == 2
    assert "invalid choice: 'tracker4'" in capsys.readouterr().err

    columns = "t [s], SI [mm], LR [mm], AP [mm]"
    monkeypatch.setitem(trace_layouts.HEADERLESS_FORMATS, "tracker4", columns)
    for extra in (["--format", "tracker4"], []):
        assert main([*argv, *extra]) == 0
        out = capsys.readouterr().out
        assert "Trace: tracker.txt (tracker4 format, no header, separated by spaces): 200 " in out
        assert "samples at 10 Hz over 19.9 s; SI [mm] -> +X, LR [mm] -> +Y, AP [mm] -> +Z" in out
        assert "OK: trajectory validated" in out
    five = tmp_path / "five.txt"  # a width no row has: the refusal names the new row too
    five.write_text("\n".join(f"{r} 0.0" for r in rows) + "\n")
    assert main(["check", str(five), "--out", str(tmp_path / "o5")]) == 2
    err = capsys.readouterr().err
    assert "no header line and 5 columns" in err
    assert f"tracker4: 4 columns, {columns}" in err


def _encoder_floor(name: str) -> dict:
    """A small study's job (module-level: a pool pickles it): the encoders' floor of one shipped
    bus robot at home, X um, with the study's "sim_s" and "wall_s" (nothing simulated)."""
    from stewart_drake.analysis.error_budget import quantization_floor
    from stewart_drake.run.scenario_io import load_scenario

    return {"X_um": 1e6 * float(quantization_floor(load_scenario(name))[3]), "sim_s": 0.0,
            "wall_s": 0.0}  # fmt: skip


def test_a_study_built_from_the_named_pieces_writes_its_table_into_a_doc(tmp_path):
    """A study is its jobs run through ``execution.runners`` (a job that fails is a row that
    says so), its table made by ``base.tables``, written between its markers by
    ``base.fileio.write_between_markers`` with ``studies.simulated_line`` under it. A small
    one (the encoders' floor of each shipped bus robot, and a robot that does not exist) put
    into a doc with text of its own: the table lands between the markers, the doc's text is
    kept, and a second run replaces the table in place. The floors are the error budget's,
    checked against the bound of half a count through the Jacobian elsewhere
    (tests/test_error_budget.py); here only that they are a paper_bus's 134 um and a
    phantom_bus's 1.04 um (526,374 counts a turn)."""
    from stewart_drake.base.fileio import write_between_markers
    from stewart_drake.base.tables import markdown_lines
    from stewart_drake.execution.runners import SerialRunner, map_outcomes
    from stewart_drake.studies import simulated_line

    markers = ("<!-- floor table: a test's study -->", "<!-- end of floor table -->")
    doc = tmp_path / "study.md"
    doc.write_text("# A page\n\nText before.\n\n## After\n\nText after.\n")
    jobs = {name: name for name in ("paper_bus", "phantom_bus", "no_such_robot")}
    for _ in range(2):
        results = map_outcomes(SerialRunner(), _encoder_floor, jobs, progress=False)
        rows = [
            [name, f"{r['X_um']:.3g}" if isinstance(r, dict) else f"failed: {r[:40]}"]
            for name, r in results.items()
        ]
        lines = markdown_lines(["robot", "X floor, um"], rows)
        block = "\n".join([markers[0], "", *lines, "", simulated_line(results, "runs"), markers[1]])
        write_between_markers(doc, markers, block)
    text = doc.read_text()
    assert text.count(markers[0]) == 1 and text.count("| paper_bus | 134 |") == 1
    assert text.startswith("# A page\n\nText before.\n\n## After\n\nText after.\n")
    assert "| phantom_bus | 1.04 |" in text  # docs/robot.md's budget: 1.04 um
    assert "| no_such_robot | failed: " in text
    assert "2 runs, 0 s simulated in 0 s of simulation wall time." in text
