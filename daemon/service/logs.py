"""Logging journald reads well: one line per record, a ``<N>`` syslog priority prefix
(journald turns it into PRIORITY=), then ``logger: message key=value …``.

Structured fields come from ``extra={"fields": {...}}``; ``log_format = "json"`` prints
one JSON object per line instead, for collectors that want it.
"""

from __future__ import annotations

import json
import logging
import sys
from typing import TextIO

_PRIORITY = {
    logging.DEBUG: 7,
    logging.INFO: 6,
    logging.WARNING: 4,
    logging.ERROR: 3,
    logging.CRITICAL: 2,
}


def _fields(record: logging.LogRecord) -> dict:
    fields = getattr(record, "fields", None)
    return dict(fields) if isinstance(fields, dict) else {}


def _value(v: object) -> str:
    s = str(v)
    return json.dumps(s) if (not s or any(ch in s for ch in ' "=\n')) else s


class JournalFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        prio = _PRIORITY.get(record.levelno, 6)
        msg = record.getMessage().replace("\n", " ")
        extra = " ".join(f"{k}={_value(v)}" for k, v in _fields(record).items())
        line = f"<{prio}>{record.name}: {msg}" + (f" {extra}" if extra else "")
        if record.exc_info:
            line += " exc=" + json.dumps(self.formatException(record.exc_info))
        return line


class JsonFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        out = {
            "ts": round(record.created, 6),
            "level": record.levelname,
            "logger": record.name,
            "msg": record.getMessage(),
            **_fields(record),
        }
        if record.exc_info:
            out["exc"] = self.formatException(record.exc_info)
        return json.dumps(out, default=str)


class _StderrHandler(logging.StreamHandler):
    """Writes to ``sys.stderr`` as it is when a record is emitted, not as it was at set-up: a
    command run in-process (as the tests run the CLI) swaps stderr and closes its copy after,
    and a handler bound to that copy failed every later record ("I/O operation on closed file")."""

    @property  # type: ignore[override]
    def stream(self) -> TextIO:
        return sys.stderr

    @stream.setter
    def stream(self, _value) -> None:  # StreamHandler.__init__ and setStream assign it
        pass


def setup_logging(level: str = "INFO", fmt: str = "journal") -> None:
    handler = _StderrHandler()
    handler.setFormatter(JsonFormatter() if fmt == "json" else JournalFormatter())
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)
