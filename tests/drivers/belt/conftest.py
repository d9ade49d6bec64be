"""The simulated belt, parametrised: the real firmware on simavr, and the Python mock.

In CI (``CI=true``) the simavr belt must build and run: missing packages fail the tests.
Elsewhere they skip with the command that installs them.
"""

from __future__ import annotations

import os

import pytest

from drivers.belt import hil

IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")


@pytest.fixture(scope="session")
def simavr_built() -> None:
    missing = hil.simavr_missing()
    if missing:
        message = f"simavr belt unavailable ({missing}): run `make system-deps`"
        if IN_CI:
            pytest.fail(message)
        pytest.skip(message)
    hil.build_firmware()


@pytest.fixture(params=hil.KINDS)
def belt_kind(request) -> str:
    if request.param == "simavr":
        request.getfixturevalue("simavr_built")
    return request.param


@pytest.fixture
def belt(belt_kind, tmp_path):
    b = hil.SimulatedBelt(belt_kind, tmp_path / "belt-tty")
    b.start()
    yield b
    b.stop()
