"""``harmonic_bench._count_faults``: the minor page faults of a route's path reads, counted
around each call and handed out per step."""

from __future__ import annotations

import mmap

import pytest

from sim.harmonic_bench import _count_faults

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
def test_the_path_reads_faults_are_counted_and_the_call_passes_through():
    route = Route()
    pending = _count_faults(route)
    assert route.path_from(1, cell=(2, 3)) == ((1,), {"cell": (2, 3)})
    quiet = pending[0]
    assert quiet < PAGES // 4  # a read that maps nothing new
    route.touch = PAGES
    route.path_from()
    route.path_from()
    assert pending[0] - quiet >= 2 * PAGES
