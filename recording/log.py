"""An MCAP file that rotates: bounded size, every message counted.

``McapLog`` writes one channel per zenoh key (registered on first use, with its schema),
``log_time`` = when the recorder heard the sample, ``publish_time`` = the message's own
stamp. Past ``max_bytes`` the file is finished (summary, index) and the next one opened:
``walk.mcap``, ``walk.001.mcap``, ``walk.002.mcap``, … each readable on its own.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from mcap.writer import Writer

from protocol import topics as T
from protocol.messages import Message

from .channels import schema_json, to_json

PROFILE = "guidebelt"


@dataclass
class LogCounts:
    written: int = 0
    files: list[Path] = field(default_factory=list)
    by_key: dict[str, int] = field(default_factory=dict)


class McapLog:
    def __init__(self, out: Path, max_bytes: int = 256 * 2**20, metadata: dict | None = None):
        if max_bytes < 64 * 1024:
            raise ValueError("max_bytes below 64 KiB: every file would hold a few messages")
        self.out = out
        self.max_bytes = max_bytes
        self.metadata = {k: str(v) for k, v in (metadata or {}).items()}
        self.counts = LogCounts()
        self._file: IO[bytes] | None = None
        self._writer: Writer | None = None
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[str, int] = {}
        self._open()

    def _path(self) -> Path:
        n = len(self.counts.files)
        return self.out if n == 0 else self.out.with_suffix(f".{n:03d}{self.out.suffix}")

    def _open(self) -> None:
        path = self._path()
        path.parent.mkdir(parents=True, exist_ok=True)
        self._file = path.open("wb")
        # Chunks are buffered in memory until full: a small one keeps a file near max_bytes.
        self._writer = Writer(self._file, chunk_size=min(2**20, self.max_bytes // 8))
        self._writer.start(profile=PROFILE, library="guidebelt")
        if self.metadata:
            self._writer.add_metadata("guidebelt", self.metadata)
        self._schemas.clear()
        self._channels.clear()
        self.counts.files.append(path)

    def _channel(self, key: str, model: type[Message]) -> int:
        writer = self._writer
        assert writer is not None
        channel = self._channels.get(key)
        if channel is None:
            schema = self._schemas.get(model.__name__)
            if schema is None:
                schema = self._schemas[model.__name__] = writer.register_schema(
                    name=f"guidebelt.{model.__name__}",
                    encoding="jsonschema",
                    data=schema_json(model),
                )
            channel = self._channels[key] = writer.register_channel(
                topic=key, message_encoding="json", schema_id=schema,
                metadata={"topic": T.topic_of(key).name},
            )  # fmt: skip
        return channel

    def write(self, key: str, msg: Message, log_time_s: float) -> None:
        if self._file is not None and self._file.tell() >= self.max_bytes:
            self._finish()
            self._open()
        assert self._writer is not None
        seq = self._seq[key] = self._seq.get(key, -1) + 1
        stamp = getattr(msg, "stamp", log_time_s)
        self._writer.add_message(
            channel_id=self._channel(key, type(msg)),
            log_time=int(log_time_s * 1e9),
            publish_time=int(stamp * 1e9),
            data=to_json(msg),
            sequence=seq % 2**32,
        )
        self.counts.written += 1
        self.counts.by_key[key] = self.counts.by_key.get(key, 0) + 1

    def _finish(self) -> None:
        if self._writer is not None:
            self._writer.finish()
            self._writer = None
        if self._file is not None:
            self._file.close()
            self._file = None

    def close(self, summary: dict | None = None) -> None:
        if summary and self._writer is not None:
            self._writer.add_metadata(
                "guidebelt.counts", {k: json.dumps(v) for k, v in summary.items()}
            )
        self._finish()
