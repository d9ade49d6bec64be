"""Planners by name (interim: the planning package's own registry replaces this)."""

from __future__ import annotations

from .backends import make_planner as _backend_planner
from .interface import GlobalPlanner, UpdateStats

PLANNERS = ("eds", "dss")


class _FullReplan(GlobalPlanner):
    def __init__(self, inner: GlobalPlanner) -> None:
        self.inner = inner
        self.name = inner.name

    def plan(self, blocked, goal) -> UpdateStats:
        return self.inner.plan(blocked, goal)

    def update(self, cells, blocked) -> UpdateStats:
        return self.inner.replan(cells, blocked)

    def replan(self, cells, blocked) -> UpdateStats:
        return self.inner.replan(cells, blocked)

    def update_and_path(self, cells, blocked, start, *, full: bool = True):
        return self.inner.update_and_path(cells, blocked, start, full=True)

    def costs(self):
        return self.inner.costs()

    def blocked(self):
        return self.inner.blocked()

    def cost_at(self, cell) -> int:
        return self.inner.cost_at(cell)

    def path(self, start):
        return self.inner.path(start)

    @property
    def goal(self):
        return self.inner.goal

    @property
    def shape(self):
        return self.inner.shape


def make_planner(name: str = "eds", backend: str = "auto", variant: str = "fast") -> GlobalPlanner:
    if name not in PLANNERS:
        raise ValueError(f"unknown planner {name!r}; choose one of {PLANNERS}")
    planner = _backend_planner(backend, variant, raw=True)
    return _FullReplan(planner) if name == "dss" else planner
