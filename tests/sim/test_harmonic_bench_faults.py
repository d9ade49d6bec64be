"""``harmonic_bench._count_faults``: the minor page faults of a route's path reads, counted
around each call and handed to the bench's note once per read, the plan's read first."""

from __future__ import annotations

import mmap

import pytest

from sim.harmonic_bench import _count_faults, _new_searches, summary

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
    _count_faults(route, notes.append)
    route.touch = PAGES  # the plan: maps pages
    assert route.path_from(1, cell=(2, 3)) == ((1,), {"cell": (2, 3)})
    route.touch = 0  # step 0: maps nothing new
    route.path_from()
    route.touch = PAGES  # step 1, the last: its note comes with its read, not a later step
    route.path_from()
    assert len(notes) == 3
    assert notes[0] >= PAGES and notes[2] >= PAGES
    assert notes[1] < PAGES // 4


def test_a_search_is_put_on_the_step_that_ran_it_not_the_plan_or_the_next():
    # Running counts after each read: the plan's (none), then steps 0..3; step 2 searched.
    assert _new_searches([0, 0, 0, 1, 1], 4) == [2]
    assert _new_searches([1, 1, 2], 2) == [1]  # the plan's own search is not a step's


@pytest.mark.timeout(10)
def test_the_summary_gives_each_replanning_row_its_figures_in_one_line():
    rows = [
        {"planner": "harmonic", "grid": 400, "step_ms": {"median": 0.5, "p99": 1.6, "max": 1.7},
         "trace": [[206, 20, 1.7], [4669, 20, 1.6], [90, 20, 0.5]], "full_searches": [0],
         "cut_searches": []},
        {"what": "a plateau row, no step"},
    ]  # fmt: skip
    (line,) = summary(rows)
    assert line.startswith("harmonic 400² median 0.5 p99 1.6 max 1.7 total 3.80")
    assert "[[206, 20, 1.7], [4669, 20, 1.6]]" in line and "full [0] cut []" in line
