"""``guidebelt goal`` and ``guidebelt status`` as a person types them, against a real daemon."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def guidebelt(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cli.app", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )


@pytest.mark.timeout(120)
def test_goal_then_status_from_the_command_line(daemon):
    endpoint = f"tcp/127.0.0.1:{daemon.port}"
    missing = guidebelt("status", "cli-user", "--connect", endpoint, "--timeout", "1")
    assert missing.returncode == 1 and "no status for 'cli-user'" in missing.stderr
    sent = guidebelt("goal", "cli-user", "2.5", "7.5", "--connect", endpoint, "--wait", "1")
    assert sent.returncode == 0, sent.stderr
    assert '"kind":"metres"' in sent.stdout and "planning" in sent.stdout
    shown = guidebelt("status", "cli-user", "--connect", endpoint)
    assert shown.returncode == 0, shown.stderr
    user_line = next(ln for ln in shown.stdout.splitlines() if ln.startswith("cli-user: "))
    status = json.loads(user_line.removeprefix("cli-user: "))
    assert status["state"] == "planning" and status["reason"] == "goal received"
    assert "cli-user" in json.loads(shown.stdout.split("daemon: ", 1)[1].splitlines()[0])["users"]
    bad = guidebelt("goal", "Not Valid", "1", "1", "--connect", endpoint)
    assert bad.returncode != 0


@pytest.mark.timeout(120)
def test_settings_changed_and_shown_from_the_command_line(daemon):
    endpoint = f"tcp/127.0.0.1:{daemon.port}"
    # The user exists once the daemon has heard of them: a goal does it.
    assert guidebelt("goal", "cli-settings", "1", "1", "--connect", endpoint, "--wait", "0.3")
    changed = guidebelt("settings", "cli-settings", "--intensity", "30", "--connect", endpoint)
    assert changed.returncode == 0, changed.stderr
    assert json.loads(changed.stdout.removeprefix("cli-settings: "))["intensity"] == 30
    shown = guidebelt("settings", "cli-settings", "--connect", endpoint)
    assert shown.returncode == 0, shown.stderr
    assert json.loads(shown.stdout.removeprefix("cli-settings: "))["intensity"] == 30
    too_strong = guidebelt("settings", "cli-settings", "--intensity", "150", "--connect", endpoint)
    assert too_strong.returncode != 0
    # Words and units change alone; the intensity set before stays.
    words = guidebelt("settings", "cli-settings", "--wording", "sides", "--units", "imperial",
                      "--connect", endpoint)  # fmt: skip
    assert words.returncode == 0, words.stderr
    now = json.loads(words.stdout.removeprefix("cli-settings: "))
    assert (now["wording"], now["units"], now["intensity"], now["voice"]) == (
        "sides", "imperial", 30, "companion"
    )  # fmt: skip
    loud = guidebelt("settings", "cli-settings", "--voice", "loud", "--connect", endpoint)
    assert loud.returncode == 2 and "companion" in loud.stderr
