"""Every number of every wire message is finite and bounded at both ends, so no value a peer
sends can reach a conversion that raises (an int64 cast, a float turned into a cell index)."""

from __future__ import annotations

import inspect
import types
import typing

import annotated_types as at
import pytest
from pydantic import BaseModel, ValidationError

import protocol.map_messages
import protocol.messages as M

WIRE = (M.__name__, protocol.map_messages.__name__)
MODELS = [
    cls
    for _, cls in inspect.getmembers(M, inspect.isclass)
    if issubclass(cls, BaseModel) and cls.__module__ in WIRE and cls is not M.Message
]


def numeric_fields():
    for cls in MODELS:
        for name, field in cls.model_fields.items():
            ann = field.annotation
            if isinstance(ann, types.UnionType):  # X | None
                args = tuple(a for a in typing.get_args(ann) if a is not type(None))
            elif typing.get_origin(ann) is None:
                args = (ann,)
            else:
                continue  # containers: their lengths are bounded, their items by their kind
            if any(a in (int, float) for a in args):
                yield cls, name, field


@pytest.mark.parametrize(
    ("cls", "name", "field"),
    list(numeric_fields()),
    ids=[f"{c.__name__}.{n}" for c, n, _ in numeric_fields()],
)
def test_every_number_on_the_wire_is_bounded_at_both_ends(cls, name, field):
    meta = field.metadata
    assert any(isinstance(m, (at.Ge, at.Gt)) for m in meta), f"{cls.__name__}.{name}: no minimum"
    assert any(isinstance(m, (at.Le, at.Lt)) for m in meta), f"{cls.__name__}.{name}: no maximum"


def test_a_pose_or_goal_far_off_any_scale_is_refused_whole():
    for bad in (dict(x=1e308, y=0.0), dict(x=0.0, y=-1e7), dict(x=0.0, y=0.0, heading=1e300)):
        with pytest.raises(ValidationError):
            M.Pose(**{"x": 0.0, "y": 0.0, "heading": 0.0, "stamp": 1.0, **bad})
    for stamp in (1e12, float("nan"), float("inf")):  # 30,000 years on, or no number at all
        with pytest.raises(ValidationError):
            M.Pose(x=0.0, y=0.0, heading=0.0, stamp=stamp)
    with pytest.raises(ValidationError):
        M.GoalMetres(x=1e308, y=0.0)
    with pytest.raises(ValidationError):
        M.GoalCell(row=10**30, col=0)
