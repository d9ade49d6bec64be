"""One MCAP channel per zenoh key, its schema the one ``guidebelt schema`` writes.

Messages are stored as JSON (message encoding ``json``, schema encoding ``jsonschema``), the
form Foxglove reads without a plugin. The two binary messages (map delta and snapshot) are
stored as the same fields with their byte strings in base64, marked ``contentEncoding:
base64`` in the schema as JSON Schema says; replay turns them back into the binary wire form.
"""

from __future__ import annotations

import base64
import json
from functools import cache

from protocol import codec
from protocol import topics as T
from protocol.messages import MapDelta, MapSnapshot, Message, StatusCode
from protocol.schema import schemas

BINARY_FIELDS: dict[type[Message], tuple[str, ...]] = {
    MapDelta: ("cells", "values"),
    MapSnapshot: ("occupancy",),
}
RECORDED = tuple(t for t in T.TOPICS if t.kind is T.Kind.PUBSUB and t.per_user)
"""Every per-user key with samples on it: inputs, outputs and the drivers' health."""
INPUTS = (T.MAP_DELTA, T.POSE, T.GOAL, T.BELT_BUTTON, T.SETTINGS_SET, T.BELT_HEALTH)
"""What the daemon takes in (``daemon/service/bridge.py``): what replay --check feeds it."""


@cache
def schema_json(model: type[Message]) -> bytes:
    sch = dict(schemas()[model.__name__])
    fields = BINARY_FIELDS.get(model, ())
    if fields:
        props = {k: dict(v) for k, v in sch["properties"].items()}
        for name in fields:
            props[name] = {**props[name], "type": "string", "contentEncoding": "base64"}
            props[name].pop("format", None)
        sch["properties"] = props
        sch["x-wire"] = {"encoding": "JSON here; binary on the wire", "wire": sch["x-wire"]}
    return json.dumps(sch, sort_keys=True).encode()


def to_json(msg: Message) -> bytes:
    fields = BINARY_FIELDS.get(type(msg))
    if not fields:
        return msg.model_dump_json().encode()
    data = msg.model_dump(mode="python")
    for name in fields:
        data[name] = base64.b64encode(data[name]).decode()
    return json.dumps(data).encode()


def from_json(model: type[Message], data: bytes) -> Message:
    """The message back from its JSON, validated like any input (a bad file is refused)."""
    fields = BINARY_FIELDS.get(model)
    if not fields:
        return codec.decode(model, data)
    try:
        raw = json.loads(data)
        for name in fields:
            raw[name] = base64.b64decode(raw[name], validate=True)
        msg = model.model_validate(raw)
    except (ValueError, KeyError, TypeError) as exc:  # pydantic's ValidationError included
        raise codec.DecodeError(StatusCode.MALFORMED, f"{model.__name__}: {exc}") from None
    # Through the wire codec once: the same checks as a live sample (a snapshot's body).
    return codec.decode(model, codec.encode(msg))
