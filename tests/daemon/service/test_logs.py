"""The daemon's log handler follows stderr: a command run in-process may swap it and close
its copy, and the records after must still be written, not fail."""

from __future__ import annotations

import io
import logging
import sys

from daemon.service.logs import setup_logging


def test_records_go_to_the_stderr_of_the_moment_not_a_closed_copy(monkeypatch, capsys):
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    try:
        swapped = io.StringIO()
        monkeypatch.setattr(sys, "stderr", swapped)
        setup_logging("INFO")
        logging.getLogger("guidebelt.test").info("while swapped")
        assert "while swapped" in swapped.getvalue()
        swapped.close()
        monkeypatch.undo()
        logging.getLogger("guidebelt.test").warning("after the copy closed")
        err = capsys.readouterr().err
        assert "after the copy closed" in err and "Logging error" not in err
    finally:
        root.handlers[:] = handlers
        root.setLevel(level)
