"""A damaged file is one typed error naming the file, never a traceback.

Property-based over the loaders (bytes in, a valid object or a typed error out): the ANN and
ratio tuner weights, a collect folder (manifest and run files), a scenario YAML, a run result.
The mutations are the faults of real life: empty, truncated, random bytes, a flipped byte (a
failed CRC), an entry missing, an object array, another format version, metadata that is not
JSON. The same examples every run (``derandomize=True``); an untyped exception fails the test
that meets it.
"""

import functools
import io
import json
import pickle
import tempfile
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from conftest import extra_missing
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stewart_drake.base.errors import (
    CorruptFileError,
    IncompleteResultsError,
    ResultsMismatchError,
    StewartError,
)
from stewart_drake.base.npz import CheckedNpz
from stewart_drake.control.tuner.ann import DEFAULT_TUNER_PATH, TunerModel
from stewart_drake.control.tuner.network import load_tuner, save_tuner
from stewart_drake.control.tuner.ratio import RatioTunerModel
from stewart_drake.execution.store import MANIFEST, ResultStore, read_manifest
from stewart_drake.run.scenario import Scenario, dump_scenario
from stewart_drake.run.scenario_io import load_scenario
from stewart_drake.tuner.collection import load_records

EXAMPLES = Counter()
VALID = Counter()  # examples that loaded, per loader (the strategies reach both ends)


def _settings(n, loader: str):
    """Hypothesis settings of n examples, and the test's own check once they are done: at least
    nine in ten examples ran, and the loader met both outcomes (some damaged files still load,
    most are refused). The counters of ``loader`` are reset first, so the check needs no other
    test and no order."""
    hypothesis_settings = settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
    )

    def decorate(test):
        test = hypothesis_settings(test)

        @functools.wraps(test)
        def counted(*args, **kwargs):
            EXAMPLES[loader] = VALID[loader] = 0
            test(*args, **kwargs)
            assert EXAMPLES[loader] >= 0.9 * n, (loader, n, EXAMPLES[loader])
            # the generated archives carry the time in their zip headers: counts vary a little
            assert 1 <= VALID[loader] < EXAMPLES[loader], (loader, VALID, EXAMPLES)

        return counted

    return decorate


def _npz(arrays: dict) -> bytes:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # pickles object arrays: what a reader refuses
    return buffer.getvalue()


def _entries(data: bytes) -> dict:
    with np.load(io.BytesIO(data)) as npz:
        return {k: npz[k] for k in npz.files}


#: Values an entry of an .npz may be replaced by (each wrong for some entry).
BAD_VALUES = [
    np.array([object()], dtype=object),
    np.str_("tanh"),
    np.zeros((2, 3)),
    np.full(12, np.nan),
    np.zeros(0),
    np.int64(2),
    np.str_("{not json"),
    np.str_("[1, 2]"),
    np.array(["a", "b"]),
    np.float64(1e300),
    np.array(True),
]


def mutations(valid: bytes, text: bool = False):
    """Bytes of ``valid`` damaged in the ways files are damaged."""
    n = len(valid)
    options = [
        st.binary(max_size=600),  # random, empty
        st.integers(0, n - 1).map(lambda k: valid[:k]),  # truncated
        st.tuples(st.integers(0, n - 1), st.integers(1, 255)).map(  # one byte changed
            lambda p: valid[: p[0]] + bytes([valid[p[0]] ^ p[1]]) + valid[p[0] + 1 :]
        ),
        st.just(valid),
    ]
    if text:
        lines = valid.decode().splitlines(keepends=True)
        options += [
            st.text(max_size=200).map(str.encode),
            st.integers(0, len(lines) - 1).map(  # a line lost
                lambda k: "".join(lines[:k] + lines[k + 1 :]).encode()
            ),
        ]
    else:
        entries = _entries(valid)
        names = sorted(entries)
        options += [
            st.sampled_from(names).map(  # an entry missing
                lambda k: _npz({a: v for a, v in entries.items() if a != k})
            ),
            st.tuples(st.sampled_from(names), st.sampled_from(BAD_VALUES)).map(
                lambda kv: _npz({**entries, kv[0]: kv[1]})
            ),
        ]
    return st.one_of(*options)


def _load(loader, path: Path, data: bytes, name: str):
    """loader(path) after writing ``data``: the object, or None after a CorruptFileError that
    names the file and pickles."""
    EXAMPLES[name] += 1
    path.write_bytes(data)
    try:
        out = loader(path)
    except CorruptFileError as err:
        assert str(path) in str(err) and err.path == str(path) and err.problem
        back = pickle.loads(pickle.dumps(err))
        assert type(back) is CorruptFileError and str(back) == str(err)
        return None
    VALID[name] += 1
    return out


# -- tuner weights --------------------------------------------------------------------------------

ANN = DEFAULT_TUNER_PATH.read_bytes()


@_settings(250, "load_tuner")
@given(data=mutations(ANN))
def test_ann_tuner_file(tmp_path, data):
    model = _load(functools.partial(load_tuner, TunerModel), tmp_path / "w.npz", data, "load_tuner")
    if model is not None:
        omega = model.predict(np.ones(12))
        assert np.all((0.1 <= omega) & (omega <= 10))


def _ratio_bytes() -> bytes:
    rng = np.random.default_rng(0)
    model = RatioTunerModel(
        rng.normal(size=(4, 16)),
        rng.normal(size=4),
        rng.normal(size=(1, 4)),
        rng.normal(size=1),
        np.zeros(16),
        np.ones(16),
        {"note": "test"},
    )
    with tempfile.TemporaryDirectory() as folder:
        return save_tuner(model, Path(folder) / "r.npz").read_bytes()


RATIO = _ratio_bytes()


@_settings(120, "load_ratio_tuner")
@given(data=mutations(RATIO))
def test_ratio_tuner_file(tmp_path, data):
    model = _load(
        functools.partial(load_tuner, RatioTunerModel), tmp_path / "r.npz", data, "load_ratio_tuner"
    )
    if model is not None:
        assert np.all(np.isfinite(model.predict(np.ones(16))))


@pytest.mark.parametrize(
    "change, problem",
    [
        (lambda e: {k: v for k, v in e.items() if k != "W2"}, "the entry 'W2' is missing"),
        (
            lambda e: {**e, "W1": np.array([None], dtype=object)},
            "the entry 'W1' holds object values",
        ),
        (
            lambda e: {**e, "format_version": np.int64(2)},
            "tuner format 2, this stewart-drake reads 1",
        ),
        (lambda e: {**e, "metadata_json": np.str_('{"mode": ')}, "'metadata_json' is not JSON"),
        (lambda e: {**e, "x_std": np.zeros(12)}, "x_std must be > 0"),
    ],
)
def test_each_fault_of_a_weight_file_is_named(tmp_path, change, problem):
    path = tmp_path / "w.npz"
    path.write_bytes(_npz(change(_entries(ANN))))
    with pytest.raises(CorruptFileError, match=problem) as info:
        load_tuner(TunerModel, path)
    assert str(info.value).startswith(f"{path} is not a valid ANN tuner weights file: ")
    assert str(info.value).endswith("retrain with `stewart-drake train` or use the shipped weights")
    for data, problem in (
        (b"", "it is empty"),
        (ANN[:3000], "BadZipFile"),
        (ANN[:500] + bytes([ANN[500] ^ 1]) + ANN[501:], "Bad CRC-32"),
    ):
        path.write_bytes(data)
        with pytest.raises(CorruptFileError, match=problem):
            load_tuner(TunerModel, path)


def test_a_corrupt_weight_file_is_one_line_from_the_cli(tmp_path, capsys):
    from stewart_drake.cli import main as cli

    weights = tmp_path / "w.npz"
    weights.write_bytes(ANN[: len(ANN) // 2])
    code = cli.main(
        [
            "run",
            "--tuner",
            "ann",
            "--tuner-weights",
            str(weights),
            "--duration",
            "0.1",
            "--no-progress",
            "--out",
            str(tmp_path / "r"),
        ]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert f"{weights} is not a valid ANN tuner weights file" in err[0]


# -- a collect folder -----------------------------------------------------------------------------


def _collect_folder(folder: Path, sizes=(20, 21)) -> dict:
    """A complete two-run collection (what ``collect`` writes, with short synthetic runs of
    ``sizes`` samples)."""
    store = ResultStore(folder, "collect", {"seed": 0}, pattern="run_*.npz")
    runs = []
    for k, (q, r) in enumerate([(0.1, 1.0), (10.0, 1.0)]):
        n = sizes[k]
        arrays = {
            "omega_Q": np.float64(q),
            "omega_R": np.float64(r),
            "t": np.arange(n) * 5e-3,
            "rho": np.full((n, 12), 0.5),
            "cost_e": np.ones(n),
            "cost_u": np.ones(n),
            "metrics": np.array(json.dumps({"rms_error": [0.0] * 6})),
            "settings_hash": np.array(store.hash),
        }
        name = f"run_{k}.npz"
        store.put(str(k), name, lambda f, a=arrays: np.savez_compressed(f, **a), n_samples=n)
        runs.append({"file": name, "omega_Q": q, "omega_R": r, "lost": None})
    store.finish(True, runs=runs + [{"file": None, "lost": "lost the platform"}])
    return {p.name: p.read_bytes() for p in folder.iterdir()}


with tempfile.TemporaryDirectory() as _folder:
    COLLECTED = _collect_folder(Path(_folder))


@_settings(200, "load_records")
@given(which=st.sampled_from([MANIFEST, "run_0.npz", "run_1.npz"]), data=st.data())
def test_collect_folder(tmp_path, which, data):
    folder = tmp_path / f"c{EXAMPLES['load_records']}"
    folder.mkdir()
    for name, content in COLLECTED.items():
        (folder / name).write_bytes(content)
    damaged = data.draw(mutations(COLLECTED[which], text=which == MANIFEST))
    EXAMPLES["load_records"] += 1
    (folder / which).write_bytes(damaged)
    try:
        records = load_records(folder)
    except CorruptFileError as err:
        assert str(folder) in err.path and err.problem
        assert pickle.loads(pickle.dumps(err)).args == err.args
        return
    except (IncompleteResultsError, ResultsMismatchError) as err:  # a JSON edit can say so
        assert str(folder) in str(err)
        return
    VALID["load_records"] += 1
    assert [r["t"].shape for r in records] == [(20,), (21,)]
    assert all(r["rho"].shape == (len(r["t"]), 12) for r in records)


@pytest.mark.parametrize(
    "which, content, problem",
    [
        (MANIFEST, lambda b: b[: len(b) // 2], "not JSON"),
        (MANIFEST, lambda b: b"", "it is empty"),
        (MANIFEST, lambda b: b"[1, 2]", "a JSON list, not an object"),
        (
            MANIFEST,
            lambda b: b.replace(b'"file": "run_0.npz"', b'"fil": "run_0.npz"'),
            "job '0' is done but names no file",
        ),
        (MANIFEST, lambda b: b.replace(b'"runs"', b'"run"'), "'runs' list is missing"),
        ("run_1.npz", lambda b: b[:100], "BadZipFile"),
        (
            "run_1.npz",
            lambda b: _npz({k: v for k, v in _entries(b).items() if k != "rho"}),
            "the entry 'rho' is missing",
        ),
        (
            "run_1.npz",
            lambda b: _npz({**_entries(b), "cost_u": np.ones(3)}),
            r"'cost_u' has shape \(3,\), expected \(21,\)",
        ),
    ],
)
def test_a_damaged_collect_folder_names_the_file_and_the_fault(tmp_path, which, content, problem):
    for name, data in COLLECTED.items():
        (tmp_path / name).write_bytes(data)
    assert len(load_records(tmp_path)) == 2
    (tmp_path / which).write_bytes(content(COLLECTED[which]))
    with pytest.raises(CorruptFileError, match=problem) as info:
        load_records(tmp_path)
    assert info.value.path == str(tmp_path / which)
    (tmp_path / "run_0.npz").unlink()
    if which != MANIFEST:
        with pytest.raises(IncompleteResultsError, match="run_0.npz is gone"):
            load_records(tmp_path)


def test_a_damaged_manifest_stops_a_resumed_study_and_train(tmp_path, capsys):
    from stewart_drake.cli import main as cli

    (tmp_path / MANIFEST).write_bytes(COLLECTED[MANIFEST][:40])
    with pytest.raises(CorruptFileError, match="is not a valid stewart-drake manifest"):
        ResultStore(tmp_path, "collect", {"seed": 0}, pattern="run_*.npz")
    with pytest.raises(CorruptFileError):
        read_manifest(tmp_path)
    code = cli.main(["train", "--data", str(tmp_path), "--out", str(tmp_path / "w.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and f"{tmp_path / MANIFEST} is not a valid" in err[0]


def test_train_on_a_data_set_too_small_to_split_says_so(tmp_path, capsys):
    if extra_missing("train"):
        pytest.skip(extra_missing("train"))
    from stewart_drake.cli import main as cli

    _collect_folder(tmp_path / "c", sizes=(1, 1))
    code = cli.main(["train", "--data", str(tmp_path / "c"), "--out", str(tmp_path / "w.npz")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and err == [
        "stewart-drake train: 2 samples cannot be split 70%/30% with "
        "samples on both sides; collect more"
    ]
    assert not (tmp_path / "w.npz").exists()


def test_a_damaged_evaluation_row_is_named(tmp_path):
    store = ResultStore(tmp_path, "evaluate", {"quick": True}, pattern="rows/*.json")
    store.put_json("a", "rows/a.json", {"case": {}})
    (tmp_path / "rows" / "a.json").write_text('{"case": {')
    with pytest.raises(
        CorruptFileError,
        match=r"rows/a.json is not a valid evaluate result: "
        r"not JSON .*run the same command again",
    ):
        store.load_json("a")


# -- scenario YAML and run results ----------------------------------------------------------------

SCENARIO = dump_scenario(Scenario(duration_s=2.0)).encode()


@_settings(150, "load_scenario")
@given(data=mutations(SCENARIO, text=True))
def test_scenario_file(tmp_path, data):
    EXAMPLES["load_scenario"] += 1
    path = tmp_path / "s.yaml"
    path.write_bytes(data)
    try:
        scenario = load_scenario(path)
    except StewartError as err:  # CorruptFileError, or a value out of range
        assert str(path) in str(err), err
        return
    VALID["load_scenario"] += 1
    assert isinstance(scenario, Scenario)


def test_scenario_faults_are_named(tmp_path):
    path = tmp_path / "s.yaml"
    for data, problem in (
        (b"", "it is empty"),
        (b"\xff\xfe\x00", "not UTF-8"),
        (
            SCENARIO[: SCENARIO.index(b"controller:") + 7],
            r"not YAML \(while scanning a simple key could not find expected ':' "
            r"at line \d+, column 8\)",
        ),
        (b"duration_s: [1", "not YAML \\(while parsing a flow sequence"),
        (b"duration_s: 'one'", "does not fit the Scenario schema"),
        (b"- 1\n- 2\n", "YAML root was a <class 'list'>"),
    ):
        path.write_bytes(data)
        with pytest.raises(CorruptFileError, match=problem) as info:
            load_scenario(path)
        assert str(info.value).startswith(f"{path} is not a valid scenario file: ")
    path.write_bytes(b"duration_s: -2\n")  # YAML fine, a value out of range
    with pytest.raises(StewartError, match=rf"{path}: duration_s must be a finite number"):
        load_scenario(path)


def test_a_damaged_run_result_is_named(tmp_path):
    from stewart_drake.run.result import load_result

    path = tmp_path / "run.npz"
    path.write_bytes(_npz({"t": np.zeros(3)}))
    with pytest.raises(CorruptFileError, match="run result file: the entry 'x' is missing"):
        load_result(path)
    path.write_bytes(_npz({"a": np.ones(2)})[:50])
    with pytest.raises(CorruptFileError, match="not a readable .npz archive"):
        CheckedNpz(path, "thing")
