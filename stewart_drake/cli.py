"""The ``stewart-drake`` command: run the paper's experiment, sweep the workspace, and more.

Each subcommand parses its arguments here and calls one function of the module that owns the idea;
bad arguments and our typed errors end in a one-line message and a non-zero exit, no traceback:
exit 2 for bad arguments and StewartError (refused input, a diverged run), 1 for a file that
cannot be read or written, 130 for Ctrl-C. Output folders are checked for writing before any
work starts, so a long run never ends in a failed save.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from .errors import StewartError


class _Parser(argparse.ArgumentParser):
    """argparse with a one-line error (argparse prints the usage block first)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _int_at_least(lowest: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < lowest:
            raise argparse.ArgumentTypeError(f"must be >= {lowest}, got {text}")
        return value

    parse.__name__ = f"integer >= {lowest}"
    return parse


def check_writable(folder: Path) -> None:
    """Make sure ``folder`` can be created (if missing) and written, without creating it.

    Walks up to the nearest existing ancestor and writes a temporary file there.
    Raises:
        InvalidConfigError: a file stands in the path, or the nearest folder is not writable.
    """
    from .errors import InvalidConfigError

    existing = folder.absolute()
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    try:
        if not existing.is_dir():
            raise NotADirectoryError(20, f"{existing} is a file")
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as err:
        raise InvalidConfigError(f"cannot write to {folder}: {err.strerror or err}; choose "
                                 f"another output with --out") from None


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def _cmd_sdf(args) -> int:
    from .plant import REFERENCE_SDF, write_sdf

    from .fileio import atomic_write

    out = Path(args.out) if args.out else REFERENCE_SDF
    text = write_sdf().encode()
    atomic_write(out, lambda f: f.write(text))
    print(f"wrote {out}")
    return 0


def _delegate(module: str, function: str):
    """A subcommand that imports ``stewart_drake.<module>`` only when it runs, then calls
    ``<function>(args)``: `stewart-drake sdf` does not pay for torch or the Simulator."""

    def command(args) -> int:
        import importlib

        return getattr(importlib.import_module(f".{module}", __package__), function)(args)

    return command


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="stewart-drake",
        description="Rotary Stewart platform on a Drake closed-chain plant, LQI + ANN control.")
    sub = parser.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="run the paper's experiment (eqs. 37-38) and plot Fig. 7")
    run.add_argument("--duration", type=_positive_float, default=10.0, help="simulated s (10)")
    run.add_argument("--trajectory", default="paper",
                     help="reference: paper, home, helix, step_<axis>, sweep_<axis> (paper)")
    run.add_argument("--controller", choices=["lqi", "pd"], default="lqi",
                     help="LQI (paper) or crank-space PD baseline (lqi)")
    run.add_argument("--omega-q", type=_positive_float, default=1.0, help="omega_Q (1)")
    run.add_argument("--omega-r", type=_positive_float, default=1.0, help="omega_R (1)")
    run.add_argument("--tuner", choices=["none", "ann"], default="none",
                     help="ANN tuner of omega_Q, omega_R (none)")
    run.add_argument("--tuner-weights", default=None,
                     help="ANN weights (default: results/tuner/ann_tuner.npz if present, "
                          "else the shipped ones)")
    run.add_argument("--out", default="results", help="output folder (results/)")
    run.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    run.add_argument("--html", default=None,
                     help="also write a standalone Meshcat replay of the run to this .html")
    run.set_defaults(func=_delegate("experiments", "run_cli"))

    col = sub.add_parser("collect", help="the 9 closed-loop runs that train the ANN tuner")
    col.add_argument("--out", default="results/collect", help="output folder")
    col.add_argument("--duration", type=_positive_float, default=10.0, help="s per run (10)")
    col.add_argument("--seed", type=_int_at_least(0), default=0, help="trajectory seed (0)")
    col.add_argument("--jobs", type=_int_at_least(0), default=0,
                     help="processes (0: one per core)")
    col.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    col.set_defaults(func=_delegate("experiments", "collect_cli"))

    tr = sub.add_parser("train", help="train the ANN tuner on collected runs")
    tr.add_argument("--data", default="results/collect", help="folder written by collect")
    tr.add_argument("--mode", choices=["paper", "best_cost"], default="best_cost",
                    help="label mode of the saved tuner (best_cost)")
    tr.add_argument("--seed", type=_int_at_least(0), default=0,
                    help="split and initialization seed (0)")
    tr.add_argument("--out", default="results/tuner/ann_tuner.npz", help="weights file")
    tr.set_defaults(func=_delegate("experiments", "train_cli"), out_is_file=True)

    ev = sub.add_parser("evaluate", help="every controller on every scenario: docs/results.md")
    ev.add_argument("--docs", default="docs", help="folder of results.md and its plots (docs/)")
    ev.add_argument("--out", default="results/evaluation", help="folder of rows.json")
    ev.add_argument("--jobs", type=int, default=0, help="processes (0: one per core)")
    ev.add_argument("--controllers", default=None,
                    help="comma-separated subset, e.g. lqi_1_1,pd,ann_best_cost (all)")
    ev.add_argument("--quick", action="store_true",
                    help="1-2 s runs: a smoke test of the pipeline, not figures to quote")
    ev.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ev.set_defaults(func=_delegate("evaluation", "evaluate_cli"))

    ws = sub.add_parser("workspace", help="workspace of states and holding torques")
    ws.add_argument("--out", default="results/workspace", help="output folder")
    ws.add_argument("--resolution", type=_int_at_least(2), default=41,
                    help="grid points per axis (41)")
    ws.add_argument("--jobs", type=_int_at_least(0), default=0,
                    help="processes (0: one per core)")
    ws.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    ws.set_defaults(func=_delegate("workspace", "workspace_cli"))

    dg = sub.add_parser("diagrams", help="rewrite diagrams/*.dot and render *.svg (Graphviz)")
    dg.add_argument("--out", default=None, help="folder (default: the repo's diagrams/)")
    dg.add_argument("--dot-only", action="store_true", help="write the .dot sources only")
    dg.set_defaults(func=_delegate("visualize", "diagrams_cli"))

    sdf = sub.add_parser("sdf", help="write the reference robot's SDF (sdf/rotary_stewart.sdf)")
    sdf.add_argument("--out", default=None, help="file to write instead")
    sdf.set_defaults(func=_cmd_sdf, out_is_file=True)

    mj = sub.add_parser("mjcf", help="write the reference robot as a MuJoCo MJCF")
    mj.add_argument("--out", default="rotary_stewart.xml",
                    help="file to write (rotary_stewart.xml in the current folder)")
    mj.set_defaults(func=_delegate("mjcf", "mjcf_cli"), out_is_file=True)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if getattr(args, "out", None):
            out = Path(args.out)
            check_writable(out.parent if getattr(args, "out_is_file", False) else out)
        return int(args.func(args) or 0)
    except StewartError as err:
        print(f"stewart-drake {args.command}: {err}", file=sys.stderr)
        return 2
    except OSError as err:                           # disk full, file vanished, permissions
        print(f"stewart-drake {args.command}: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"stewart-drake {args.command}: interrupted; partial outputs were not written",
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
