"""JSON Schema of every wire message, with the binary layout where the wire is binary."""

from __future__ import annotations

import json
from pathlib import Path

from .messages import MAX_DELTA_CELLS, Message
from .topics import TOPICS, Kind, wire_models

MESSAGES: tuple[type[Message], ...] = wire_models()
"""Derived from the topic table: a message on any key is here, none can be forgotten."""

BINARY_LAYOUT = {
    "MapDelta": {
        "encoding": "binary, little-endian",
        "header": "magic 'GBMD', u16 version=1, u16 flags=0, u32 seq, u32 height, u32 width, "
        "f64 stamp, u32 count",
        "body": "count x u32 flat cell index (row * width + col), then count x u8 value",
        "max_count": MAX_DELTA_CELLS,
    },
    "MapSnapshot": {
        "encoding": "binary, little-endian",
        "header": "magic 'GBMS', u16 version=1, u16 flags=0, u32 seq, u32 height, u32 width, "
        "f64 stamp, u32 nbytes",
        "body": "nbytes of zlib-compressed uint8 occupancy, height * width bytes in C order",
    },
}


def schemas() -> dict[str, dict]:
    out = {}
    for model in MESSAGES:
        sch = model.model_json_schema()
        sch["x-wire"] = BINARY_LAYOUT.get(model.__name__, {"encoding": "JSON, UTF-8"})
        # Where it travels, so a client in another language needs no other document.
        sch["x-topics"] = [
            {
                "key": t.selector(None),
                "kind": str(t.kind),
                "from": t.producer,
                "to": t.consumers,
                # The certificate roles the daemon's access rules let send and receive it.
                "may_send": sorted(t.writers),
                "may_receive": sorted(t.readers),
            }
            for t in TOPICS
            if t.model is model
        ]
        out[model.__name__] = sch
    return out


def topics_table() -> str:
    """The topic table as Markdown: one row per key, for people rather than programs."""
    rows = [
        "| key | message | kind | from | to | may send | may receive | reliability | congestion "
        "| priority | express |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for t in TOPICS:
        q = t.qos
        model = t.model.__name__ if t.model is not None else "-"
        qos = [q.reliability, q.congestion, q.priority, "yes" if q.express else "no"]
        if t.kind is Kind.LIVELINESS:
            qos = ["-"] * 4  # a token carries no samples: nothing to queue or drop
        roles = [", ".join(sorted(t.writers)), ", ".join(sorted(t.readers))]
        cells = [f"`{t.selector(None)}`", model, t.kind, t.producer, t.consumers, *roles, *qos]
        rows.append("| " + " | ".join(map(str, cells)) + " |")
    return "\n".join(rows) + "\n"


def write_schemas(folder: Path) -> list[Path]:
    """One ``<Message>.schema.json`` per wire message, and ``topics.md``."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, sch in schemas().items():
        path = folder / f"{name}.schema.json"
        path.write_text(json.dumps(sch, indent=2, sort_keys=True) + "\n")
        paths.append(path)
    table = folder / "topics.md"
    table.write_text(topics_table())
    return [*paths, table]
