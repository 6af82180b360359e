"""The tuner's commands: ``stewart-drake collect`` (the 9 closed-loop runs of its data set) and
``train`` (the ANN fitted on them, torch)."""

from __future__ import annotations

from pathlib import Path

from ..execution.options import (
    add_runner_arguments,
    add_scenario_arguments,
    int_at_least,
    positive_float,
    runner_from_args,
    say_if_compiling,
)


def register(sub) -> None:
    """Add the ``collect`` and ``train`` commands to ``sub``, the ``stewart-drake`` subparsers."""
    _add_collect_command(sub)
    _add_train_command(sub)


def _add_collect_command(sub) -> None:
    """The ``collect`` command's options."""
    col = sub.add_parser("collect", help="the 9 closed-loop runs that train the ANN tuner")
    add_scenario_arguments(col, "the scenario the runs share")
    col.add_argument("--out", default="results/collect", help="output folder")
    col.add_argument(
        "--duration",
        type=positive_float,
        default=10.0,
        metavar="SECONDS",
        help="simulated s per run",
    )
    col.add_argument("--seed", type=int_at_least(0), default=0, help="trajectory seed")
    add_runner_arguments(col)
    col.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    col.set_defaults(func=_cmd_collect, out_sub=("diverged",))


def _cmd_collect(args) -> int:
    """``stewart-drake collect``: the 9 closed-loop runs of the tuner's data set."""
    from ..run.scenario_io import load_scenario
    from .collection import collect

    base = load_scenario(args.scenario, args.set or ())
    runner = runner_from_args(args)
    say_if_compiling("collect")
    manifest = collect(
        args.out,
        seed=args.seed,
        duration_s=args.duration,
        runner=runner,
        progress=not args.no_progress,
        base=base,
    )
    print(
        f"{len(manifest['runs'])} runs, {manifest['n_samples']} samples in {args.out} "
        f"({manifest['ran']} run now, {manifest['reused']} found on disk)"
    )
    for run in manifest["runs"]:
        rms = run["rms_error"]
        head = f"  omega_Q={run['omega_Q']:<4g} omega_R={run['omega_R']:<4g} "
        if run.get("lost"):
            print(head + f"lost the platform ({run['lost']}); no data")
            continue
        print(
            head + f"RMS phi {1e3 * rms[0]:.3f} mrad, Z {1e3 * rms[5]:.3f} mm, "
            f"sum T^2 dt {run['sum_T2_dt']:.3g}"
        )
    if manifest["ran"]:
        print(
            f"speedup over one process: {manifest['speedup']:.2f} "
            f"({manifest['sum_job_s']:.1f} s of runs in {manifest['wall_s']:.1f} s wall, "
            f"{manifest['workers']} workers)"
        )
    return 0


def _add_train_command(sub) -> None:
    """The ``train`` command's options."""
    tr = sub.add_parser("train", help="train the ANN tuner on collected runs (needs torch)")
    tr.add_argument("--data", default="results/collect", help="folder written by collect")
    tr.add_argument(
        "--mode",
        choices=["paper", "best_cost"],
        default="best_cost",
        help="label mode of the saved tuner",
    )
    tr.add_argument("--seed", type=int_at_least(0), default=0, help="split and initialization seed")
    tr.add_argument("--out", default="results/tuner/ann_tuner.npz", help="weights file")
    tr.set_defaults(func=_cmd_train, out_is_file=True)


def _cmd_train(args) -> int:
    """``stewart-drake train``: fit the tuner in both label modes, save one. The data are
    checked first, then that torch is there."""
    from ..base.errors import InvalidConfigError, MissingExtraError
    from . import collection

    records = collection.load_records(args.data)
    if len(records) < 2:
        raise InvalidConfigError(
            f"{len(records)} of the runs in {args.data} kept the platform (the others lost the "
            f"platform): too few to train on; collect with a scenario the motors can follow"
        )
    try:
        import torch  # noqa: F401 - only to say which extra is missing
    except ImportError:
        raise MissingExtraError(
            "`stewart-drake train` needs torch: install PyTorch's CPU build, then pip install "
            "'stewart-drake[train]' (README: Install)"
        ) from None
    from ..control.tuner.network import save_tuner
    from ..control.tuning import AnnTunerDriver
    from ..run.scenario import Scenario
    from .training import build_dataset, train

    reports = {}
    for mode in ("paper", "best_cost"):
        dataset = build_dataset(records, mode=mode)
        model, report = train(
            dataset,
            seed=args.seed,
            metadata={
                "label_mode": mode,
                "data": str(args.data),
                "feature_window": AnnTunerDriver().feature_window,
                "feature_period_s": Scenario().control_period_s,
            },
        )
        reports[mode] = (model, report)
        r2 = report["val_r2"]
        r2_text = ", ".join(f"{k} {v:.3f}" for k, v in r2.items()) if isinstance(r2, dict) else r2
        print(
            f"{mode:>9} labels: {dataset.info['n_samples']} samples, val loss "
            f"{report['val_loss']:.4f} (from {report['val_loss_initial']:.4f}), "
            f"validation R^2: {r2_text}"
        )
    model, _ = reports[args.mode]
    out = Path(args.out)
    save_tuner(model, out)
    print(f"wrote {out} (label mode {args.mode})")
    return 0
