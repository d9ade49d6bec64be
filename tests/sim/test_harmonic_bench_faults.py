"""``harmonic_bench._watch_reads``: the minor page faults, numba loads and time off the CPU of
a route's path reads, counted around each call and handed to the bench's note once per read,
the plan's read first."""

from __future__ import annotations

import mmap
import sys
import time
import types

import numba
import pytest

from sim.harmonic_bench import _new_searches, _watch_reads, summary

PAGES = 64


class Route:
    """A route whose path read maps ``touch`` fresh pages (anonymous memory, a fault each)."""

    def __init__(self) -> None:
        self.touch = 0

    def path_from(self, *args, **kwargs):
        if self.touch:
            with mmap.mmap(-1, self.touch * mmap.PAGESIZE) as fresh:
                for page in range(self.touch):
                    fresh[page * mmap.PAGESIZE] = 1
        return args, kwargs


@pytest.mark.timeout(30)
def test_each_path_reads_faults_go_to_its_own_note_and_the_call_passes_through():
    route = Route()
    notes: list[int] = []
    _watch_reads(route, lambda faults, _loaded, _off: notes.append(faults))
    route.touch = PAGES  # the plan: maps pages
    assert route.path_from(1, cell=(2, 3)) == ((1,), {"cell": (2, 3)})
    route.touch = 0  # step 0: maps nothing new
    route.path_from()
    route.touch = PAGES  # step 1, the last: its note comes with its read, not a later step
    route.path_from()
    assert len(notes) == 3
    assert notes[0] >= PAGES and notes[2] >= PAGES
    assert notes[1] < PAGES // 4


@pytest.mark.timeout(60)
def test_a_read_that_compiles_a_product_function_or_sleeps_says_so(monkeypatch):
    # A product module whose numba function compiles on its first call (not cached: nothing
    # is written beside the sources).
    fake = types.ModuleType("daemon._bench_probe")
    fake.twice = numba.njit(lambda x: 2 * x)
    monkeypatch.setitem(sys.modules, fake.__name__, fake)
    notes: list[tuple[list[str], float]] = []

    class Reader:
        def path_from(self, what: str) -> None:
            if what == "compile":
                assert fake.twice(3) == 6
            elif what == "sleep":
                time.sleep(0.02)

    route = Reader()
    _watch_reads(route, lambda _faults, loaded, off: notes.append((loaded, off)))
    for what in ("compile", "again", "sleep"):
        route.path_from(what)
    assert [loaded for loaded, _ in notes] == [["daemon._bench_probe.twice"], [], []]
    assert notes[2][1] >= 15.0  # 20 ms asleep: off the CPU, whatever the machine's load


def test_a_search_is_put_on_the_step_that_ran_it_not_the_plan_or_the_next():
    # Running counts after each read: the plan's (none), then steps 0..3; step 2 searched.
    assert _new_searches([0, 0, 0, 1, 1], 4) == [2]
    assert _new_searches([1, 1, 2], 2) == [1]  # the plan's own search is not a step's


@pytest.mark.timeout(10)
def test_the_summary_gives_each_replanning_row_its_figures_in_one_line():
    rows = [
        {"planner": "harmonic", "grid": 400, "step_ms": {"median": 0.5, "p99": 1.6, "max": 1.7},
         "trace": [[206, 20, 1.7], [4669, 20, 1.6], [90, 20, 0.5]], "full_searches": [0],
         "cut_searches": [], "loaded": {"2": ["daemon.x.f"]}, "off_cpu_ms": [0.1, 0.9, 0.0]},
        {"what": "a plateau row, no step"},
    ]  # fmt: skip
    (line,) = summary(rows)
    assert line.startswith("harmonic 400² median 0.5 p99 1.6 max 1.7 total 3.80")
    assert line.endswith("loaded [2] off-cpu max 0.9 at 1")
    assert "[[206, 20, 1.7], [4669, 20, 1.6]]" in line and "full [0] cut []" in line
