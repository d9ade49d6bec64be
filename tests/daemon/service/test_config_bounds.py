"""Safe defaults and a bounded config: no multicast unless asked for, no value outside its range,
and a config that cannot start the daemon is one line on stderr, not a traceback."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import ValidationError

from daemon.service.config import DaemonConfig
from protocol.settings import ZenohSettings

ROOT = Path(__file__).resolve().parents[3]


def test_nothing_is_multicast_by_default():
    assert ZenohSettings().multicast_scouting is False
    assert DaemonConfig().zenoh.multicast_scouting is False


@pytest.mark.parametrize(
    "field, value",
    [
        ("cell_m", 0.0), ("cell_m", 5.0), ("user_radius_m", -0.1), ("user_radius_m", 3.0),
        ("stale_pose_s", float("nan")), ("stale_pose_s", float("inf")), ("max_users", 0),
        ("max_users", 10**9), ("tick_s", 3600.0), ("snapshot_timeout_s", 0.0),
        ("reassure_s", -1.0), ("intensity", 101),
        ("low_battery_v", 100.0), ("landmarks", {"door": (float("nan"), 1.0)}),
        ("landmarks", {"a/b": (1.0, 1.0)}), ("daemon_id", ""), ("voice", "loud"),
    ],
)  # fmt: skip
def test_every_value_is_bounded(field, value):
    with pytest.raises(ValidationError):
        DaemonConfig(**{field: value})


def test_zenoh_endpoints_are_locators_and_few():
    assert ZenohSettings(listen=["tcp/127.0.0.1:7447"]).listen == ["tcp/127.0.0.1:7447"]
    for bad in (["127.0.0.1:7447"], ["tcp/"], ["tcp/" + "x" * 300], ["tcp/a:1"] * 17):
        with pytest.raises(ValidationError):
            ZenohSettings(listen=bad)


@pytest.mark.timeout(60)
@pytest.mark.parametrize(
    "env, file_text, said",
    [
        ({"GUIDEBELT_CELL_M": "-1"}, None, "cell_m: Input should be greater than 0 (got '-1')"),
        ({"GUIDEBELT_STALE_POSE_S": "nan"}, None, "stale_pose_s: Input should be a finite number"),
        ({}, "bogus = 1\n", "bogus: Extra inputs are not permitted"),
        ({}, "cell_m = [\n", "bad config: "),
        ({}, '[zenoh]\nlisten = ["tls/127.0.0.1:0"]\n[zenoh.tls]\nroot_ca = "/nope/ca.pem"\n'
             'certificate = "/nope/d.pem"\nprivate_key = "/nope/d.key"\n',
         "zenoh.tls.root_ca: /nope/ca.pem not found; zenoh.tls.certificate: /nope/d.pem not found"),
        ({}, '[zenoh]\nlisten = ["tcp/127.0.0.1:0"]\n[zenoh.tls]\nroot_ca = "a"\n'
             'certificate = "b"\nprivate_key = "c"\n', "every endpoint must be tls/"),
    ],
)  # fmt: skip
def test_a_bad_config_is_one_line_and_exit_status_2(tmp_path, env, file_text, said):
    config = ""
    if file_text is not None:
        config = str(tmp_path / "g.toml")
        Path(config).write_text(file_text)
    run = subprocess.run(
        [sys.executable, "-m", "cli.app", "run"],
        cwd=ROOT,
        env={**os.environ, "GUIDEBELT_CONFIG": config, "PYTHONPATH": str(ROOT), **env},
        capture_output=True,
        text=True,
        timeout=50,
    )
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("guidebelt run: bad config: "), run.stderr
    assert said in lines[0] and "Traceback" not in run.stderr
