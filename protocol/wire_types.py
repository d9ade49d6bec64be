"""What every wire message is built from: the base model and the bounded number types.

Every model forbids unknown fields and is frozen, so a message is either valid whole or
rejected whole. Every number on the wire is finite and bounded, so none can reach a conversion
that raises (an int64 cast, a float → cell index) however hostile the sender.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

MOTORS = ("front", "right", "back", "left")
"""Belt motor order, clockwise from the front, in every message and frame."""

Intensity = Annotated[int, Field(ge=0, le=255)]

MAX_STAMP = 1e10
"""Seconds since the Unix epoch (the year 2286)."""
Stamp = Annotated[float, Field(ge=0, le=MAX_STAMP, allow_inf_nan=False)]
Metres = Annotated[float, Field(ge=-1e6, le=1e6, allow_inf_nan=False)]
"""A position: a thousand kilometres from the map's origin is off any map guidebelt keeps."""
Radians = Annotated[float, Field(ge=-1e3, le=1e3, allow_inf_nan=False)]
Count = Annotated[int, Field(ge=0, le=2**53)]
"""A counter: exact in a float64 (JSON readers in other languages)."""
Amount = Annotated[float, Field(ge=0, le=1e9, allow_inf_nan=False)]
"""A non-negative quantity: a duration, a distance."""
MAX_SIDE = 4096
"""Largest map side (cells) any message may describe."""


class Message(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)
