"""The hardened unit runs the daemon as shipped, with its worker processes: every system call
a daemon with the shipped ``workers`` makes from start to SIGTERM (traced by strace, its
children included) is one the unit's ``SystemCallFilter=`` allows (systemd kills a process
on any other), and the belt driver, the last hop to the motors, is scheduled above the
daemon's real-time workers, which may now keep both cores busy."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from daemon.service.config import load_config
from daemon.service.embedded import free_port

ROOT = Path(__file__).resolve().parents[3]
DAEMON_UNIT = ROOT / "systemd" / "guidebelt.service"
BELT_UNIT = ROOT / "systemd" / "guidebelt-belt@.service"
CALL = re.compile(r"^\d+\s+([a-z0-9_]+)\(", re.MULTILINE)


def _tool(name: str) -> str:
    path = shutil.which(name)
    if path is None:
        if os.environ.get("CI"):
            pytest.fail(f"{name} missing in CI: `make system-deps` installs it")
        pytest.skip(f"{name} not installed")
    return path


def allowed_calls(unit: Path, analyze: str) -> set[str]:
    """The system calls a unit's ``SystemCallFilter=`` lines allow, groups expanded as
    ``systemd-analyze syscall-filter`` lists them (``~`` lines take calls away)."""
    listing = subprocess.run(
        [analyze, "syscall-filter", "--no-pager"], capture_output=True, text=True, timeout=30
    ).stdout
    groups: dict[str, list[str]] = {}
    current = None
    for line in listing.splitlines():
        if line.startswith("@"):
            current = line.strip()
            groups[current] = []
        elif current and line.strip() and not line.strip().startswith("#"):
            groups[current].append(line.strip())

    def expand(names: list[str]) -> set[str]:
        out: set[str] = set()
        for name in names:
            out |= expand(groups[name]) if name.startswith("@") else {name}
        return out

    allowed: set[str] = set()
    for line in unit.read_text().splitlines():
        if line.startswith("SystemCallFilter="):
            value = line.removeprefix("SystemCallFilter=")
            if value.startswith("~"):
                allowed -= expand(value[1:].split())
            else:
                allowed |= expand(value.split())
    assert allowed, f"{unit.name} has no SystemCallFilter="
    return allowed


def _daemon_under(tracer: int, timeout: float = 10.0) -> int:
    """The ``cli.app run`` process strace started (its child, found by its command line).

    The command line must be the interpreter's own: strace forks short-lived children of its
    own at start (its ptrace probes), whose command line is strace's and so also names
    ``cli.app``. One listed in its moment was taken for the daemon (1 run in 5 with two busy
    loops beside it): the SIGTERM then found no such process, and the daemon, never killed
    by its pid, outlived the test with its workers."""
    want = [sys.executable.encode(), b"-m", b"cli.app"]
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for entry in Path("/proc").iterdir():
            if not entry.name.isdigit():
                continue
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
                cmdline = (entry / "cmdline").read_bytes()
            except (OSError, ValueError, IndexError):  # gone meanwhile
                continue
            if ppid == tracer and cmdline.split(b"\0")[:3] == want:
                return int(entry.name)
        time.sleep(0.05)
    raise AssertionError("strace started no daemon")


@pytest.mark.timeout(120)
def test_the_shipped_daemon_with_its_workers_makes_no_system_call_its_unit_forbids(tmp_path):
    strace, analyze = _tool("strace"), _tool("systemd-analyze")
    probe = subprocess.run(
        [strace, "-qq", "-o", os.devnull, "true"], capture_output=True, timeout=30
    )
    if probe.returncode != 0:  # a container without ptrace: the environment's limit, not the unit's
        pytest.skip(f"strace cannot trace here: {probe.stderr.decode(errors='replace').strip()}")
    allowed = allowed_calls(DAEMON_UNIT, analyze)
    workers = load_config(ROOT / "systemd" / "guidebelt.toml").workers
    assert workers >= 2  # as shipped: the users shared among worker processes
    trace = tmp_path / "trace"
    env = {
        **os.environ,
        "PYTHONPATH": str(ROOT),
        "GUIDEBELT_CONFIG": "",
        "GUIDEBELT_WORKERS": str(workers),
        "GUIDEBELT_BACKEND": "cpu",
        "GUIDEBELT_STATE_DIR": str(tmp_path / "state"),
        "GUIDEBELT_ZENOH__LISTEN": f'["tcp/127.0.0.1:{free_port()}"]',
    }
    argv = [strace, "-f", "-qq", "-o", str(trace), sys.executable, "-m", "cli.app", "run"]
    proc = subprocess.Popen(argv, cwd=ROOT, env=env, stderr=subprocess.PIPE, text=True)
    daemon = None
    try:
        daemon = _daemon_under(proc.pid)
        assert proc.stderr is not None
        for line in proc.stderr:  # the parent's "ready" names its workers
            if "guidebelt.supervisor" in line and "ready" in line:
                break
        else:
            raise AssertionError("the daemon did not start")
        os.kill(daemon, signal.SIGTERM)
        assert proc.wait(60) == 0
    finally:
        # strace killed leaves its tracee running: the daemon is stopped by its own pid (its
        # workers follow it by PDEATHSIG).
        if daemon is not None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(daemon, signal.SIGKILL)
        if proc.poll() is None:
            proc.kill()
        proc.wait(10)
    text = trace.read_text()
    started = set(re.findall(r"^(\d+)\s+execve\(", text, re.MULTILINE))
    assert len(started) >= 1 + workers  # the daemon and its workers
    assert set(CALL.findall(text)) - allowed == set()


def _priority(unit: Path) -> tuple[str, int]:
    text = unit.read_text()
    policy = re.search(r"^CPUSchedulingPolicy=(\w+)", text, re.MULTILINE)
    prio = re.search(r"^CPUSchedulingPriority=(\d+)", text, re.MULTILINE)
    return (policy.group(1) if policy else "other", int(prio.group(1)) if prio else 0)


def test_the_belt_driver_is_scheduled_above_the_daemons_workers():
    """The workers inherit the daemon's SCHED_FIFO: two busy ones may take both cores, and a
    belt driver below them would relay STOP only in the kernel's 5 % of leftover time."""
    daemon, belt = _priority(DAEMON_UNIT), _priority(BELT_UNIT)
    assert daemon[0] == belt[0] == "fifo"
    assert belt[1] > daemon[1]
    assert "RestrictRealtime=yes" not in BELT_UNIT.read_text()  # systemd sets it at start
