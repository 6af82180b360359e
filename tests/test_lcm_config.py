"""A scenario's ``lcm`` section: the URLs a run may publish on, and one refused at validation
or, when LCM cannot open it, as one line before the run (exit 2). No scenario value may make
LCM create, truncate or write a file."""

import os
import socket

import pytest

from stewart_drake.base.errors import InvalidConfigError
from stewart_drake.cli.main import main
from stewart_drake.station import lcm_publish
from stewart_drake.station.lcm_publish import LcmConfig, check_lcm_url, make_lcm

#: What a file outside the output holds before each attempt, and must hold after.
CONTENT = b"export PATH=$HOME/bin:$PATH\n"


def _cli_lines(capsys) -> list[str]:
    err = capsys.readouterr().err.strip().splitlines()
    return [line for line in err if "compiling the LQI" not in line]  # once per machine


def _run_with(lcm: str, *extra: str) -> list[str]:
    return ["run", "--set", f"lcm={lcm}", "--set", "duration_s=0.05", *extra]


def _every_url_lcm_knows(tmp_path) -> list[str]:
    """Every provider of the LCM that Drake links (udpm, mpudpm, tcpq, memq, file), in forms
    that LCM opens, and a few it does not know."""
    kept, absent = tmp_path / "kept.sh", tmp_path / "absent.log"
    urls = []
    for target in (kept, absent, "relative.log"):
        urls += [f"file://{target}"]
        urls += [f"file://{target}?mode={mode}" for mode in ("w", "a", "r", "rw", "x")]
        urls += [f"file://{target}?speed=2&mode=w"]
    return urls + [
        "file://",
        "FILE:///etc/passwd",
        "tcpq://127.0.0.1:1",
        "tcpq://127.0.0.1:7700",
        "mpudpm://239.255.76.67:7667",
        "mpudpm://239.255.76.67:7667?nports=4",
        "udp://127.0.0.1:7667",
        "bogus://x",
        "memq://x",
        "memq://?mode=w",
        "udpm://999.1.1.1:7667",
        "udpm://10.0.0.1:7667",
        "udpm://localhost:7667",
        "udpm://239.255.76.67",
        "udpm://239.255.76.67:0",
        "udpm://239.255.76.67:65536",
        "udpm://239.255.76.67:7667?ttl=256",
        "udpm://239.255.76.67:7667?ttl=-1",
        "udpm://239.255.76.67:7667?transmit_only=1",
        "udpm://239.255.76.67:7667?ttl=0&ttl=1",
        "239.255.76.67:7667",
    ]


def test_no_scenario_url_can_create_truncate_or_write_a_file(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # where a relative file:// would land
    kept = tmp_path / "kept.sh"
    kept.write_bytes(CONTENT)
    urls = _every_url_lcm_knows(tmp_path)
    assert sum(url.startswith("file://") for url in urls) == 22
    for url in urls:
        code = main(_run_with(f'{{url: "{url}"}}', "--out", str(tmp_path / "out" / "run.npz")))
        lines = _cli_lines(capsys)
        assert code == 2, url
        assert len(lines) == 1 and f"lcm.url {url!r}" in lines[0], (url, lines)
        assert kept.read_bytes() == CONTENT, url
        assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.sh"], url


@pytest.mark.parametrize(
    "url",
    [
        "memq://",
        "udpm://239.255.76.67:7667",
        "udpm://239.255.76.67:7667?ttl=0",
        "udpm://224.0.0.251:5353?ttl=1&recv_buf_size=2097152",
        "udpm://239.0.0.1:65535?ttl=255",
    ],
)
def test_what_is_meant_is_accepted(url):
    check_lcm_url(url)
    LcmConfig(url=url).validate(1e-3)


def test_the_refusal_says_what_to_write_instead():
    with pytest.raises(InvalidConfigError) as err:
        check_lcm_url("file:///home/user/.bashrc?mode=w")
    message = str(err.value)
    assert "lcm.url 'file:///home/user/.bashrc?mode=w'" in message
    assert ".npz" in message and '"memq://"' in message and "udpm://" in message


def test_lcm_default_url_from_the_environment_is_checked_before_lcm_opens_it(tmp_path, monkeypatch):
    target = tmp_path / "log.lcm"
    monkeypatch.setenv("LCM_DEFAULT_URL", f"file://{target}?mode=w")
    with pytest.raises(InvalidConfigError, match="LCM_DEFAULT_URL 'file://"):
        make_lcm("")
    assert not target.exists()


def test_equal_status_and_command_channels_are_refused(capsys):
    code = main(_run_with('{url: "memq://", status_channel: BUS, command_channel: BUS}'))
    lines = _cli_lines(capsys)
    assert code == 2 and len(lines) == 1
    assert "lcm.status_channel and lcm.command_channel are both 'BUS'" in lines[0]


def test_a_channel_lcm_would_drop_is_refused():
    with pytest.raises(InvalidConfigError, match="lcm.status_channel .* at most 63"):
        LcmConfig(status_channel="S" * 64).validate(1e-3)
    LcmConfig(status_channel="S" * 63).validate(1e-3)


def _taken_port():
    """A UDP socket holding a port without SO_REUSEADDR: LCM's udpm cannot bind it."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("0.0.0.0", 0))
    return sock, sock.getsockname()[1]


def test_a_url_lcm_cannot_open_is_one_line_exit_2_before_the_run(tmp_path, capfd):
    sock, port = _taken_port()
    url = f"udpm://239.255.76.67:{port}?ttl=0"
    out = tmp_path / "run.npz"
    with sock:
        code = main(_run_with(f'{{url: "{url}"}}', "--out", str(out)))
    lines = _cli_lines(capfd)
    assert code == 2
    assert len(lines) == 1, lines  # LCM's own "bind: Address already in use" is in it, once
    assert f"lcm.url {url!r}: LCM cannot open it (bind: Address already in use)" in lines[0]
    assert not out.exists()


def test_a_url_lcm_falls_back_from_is_caught_by_the_round_trip(monkeypatch):
    """Where LCM cannot open a URL, Drake goes on with an in-process queue (nothing leaves the
    process, no exception): the check's second instance receives nothing and says so. The
    validation is bypassed here to reach that check with a provider that fails at open."""
    monkeypatch.setattr(lcm_publish, "check_lcm_url", lambda url, what: None)
    with pytest.raises(InvalidConfigError) as err:
        make_lcm("tcpq://127.0.0.1:1")
    message = str(err.value)
    assert "nothing published on it arrives" in message and "Connection refused" in message
    assert "\n" not in message


def test_memq_is_made_without_a_round_trip():
    lcm = make_lcm("memq://")
    assert lcm.get_lcm_url() == "memq://"


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="POSIX")
def test_the_scenario_file_cannot_set_a_file_url_either(tmp_path, capsys):
    target = tmp_path / "victim"
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(f'lcm: {{url: "file://{target}?mode=w"}}\nduration_s: 0.05\n')
    code = main(["run", "--scenario", str(scenario)])
    lines = _cli_lines(capsys)
    assert code == 2 and len(lines) == 1 and "lcm.url 'file://" in lines[0]
    assert not target.exists()
