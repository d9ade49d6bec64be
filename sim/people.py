"""People walking through the simulated world: the moving obstacles a camera must see.

Each person paces a straight segment of free floor back and forth at a walking speed,
a 25 cm-radius, 1.75 m-tall column in the ``Scene3D`` and OCCUPIED in the 2-D truth while
they stand there. A person keeps ``keep_m`` from the user (they stop and wait, as people do
when someone is in their way), so every collision a walk counts is the user's own; after
``patience_s`` of waiting they turn back along their lane, as people do for someone who
does not move on (a blind user waiting for them to pass would otherwise wait for ever: seed
1's camera walk stood 35 s in NO_PATH facing a person who waited 1.1 m away). When a
person walks on, the cells they stood on are floor again: a mapper that does not clear
them leaves a ghost on the map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daemon.planning.inflation import dilate

from .scene3d import PERSON, Scene3D

RADIUS_M = 0.25
HEIGHT_M = 1.75


@dataclass
class Person:
    a: tuple[float, float]
    b: tuple[float, float]
    speed: float
    s: float = 0.0
    """Distance walked along a → b → a …, metres."""
    waited: float = 0.0
    """Seconds waited for the user so far."""

    @property
    def length(self) -> float:
        return math.hypot(self.b[0] - self.a[0], self.b[1] - self.a[1])

    def turn_back(self) -> None:
        """The same place, walking the other way (``where`` is mirrored about the lane's ends)."""
        n2 = 2 * self.length
        if n2 > 0:
            self.s = (n2 - self.s % n2) % n2

    def where(self, s: float | None = None) -> tuple[float, float]:
        s = self.s if s is None else s
        n = self.length
        f = (s % (2 * n)) / n if n > 0 else 0.0
        f = f if f <= 1 else 2 - f
        return (self.a[0] + f * (self.b[0] - self.a[0]), self.a[1] + f * (self.b[1] - self.a[1]))


class Movers:
    """The people of one walk, seeded; ``advance`` moves them, ``stamp`` draws them."""

    def __init__(self, static: Scene3D, true_static: np.ndarray, known: np.ndarray,
                 avoid: list[tuple[int, int]], count: int = 3, seed: int = 0,
                 keep_m: float = 0.8, patience_s: float = 5.0) -> None:  # fmt: skip
        """People pace lanes of 2-4 m between the known obstacles (away from the start and
        the goal); the small unknown obstacles on a lane are cleared, as people keep their
        way free, so ``static`` and ``true_static`` are copied and carved."""
        self.static = static.copy()
        self.true_static = true_static.copy()
        self.keep_m = keep_m
        self.patience_s = patience_s
        self.people: list[Person] = []
        self._cells: list[tuple[np.ndarray, np.ndarray]] = []
        rng = np.random.default_rng([seed, 7])
        cell = static.cell_m
        lane = math.ceil((RADIUS_M + 0.1) / cell)
        clear = ~dilate(known == 1, lane)
        for rc in avoid:  # no one paces across the start or the goal
            clear[max(0, rc[0] - 10) : rc[0] + 11, max(0, rc[1] - 10) : rc[1] + 11] = False
        rows, cols = np.nonzero(clear)
        h = static.shape[0]
        for _ in range(200 * count):
            if len(self.people) >= count or rows.size == 0:
                break
            i, j = rng.integers(0, rows.size, size=2)
            a = ((cols[i] + 0.5) * cell, (h - rows[i] - 0.5) * cell)
            b = ((cols[j] + 0.5) * cell, (h - rows[j] - 0.5) * cell)
            length = math.hypot(b[0] - a[0], b[1] - a[1])
            if not 2.0 <= length <= 4.0 or not self._clear_line(clear, a, b):
                continue
            self.people.append(Person(a, b, float(rng.uniform(0.5, 1.0))))
            self._carve(a, b, lane)
        self.scene = self.static.copy()

    def _carve(self, a: tuple[float, float], b: tuple[float, float], lane: int) -> None:
        h, w = self.true_static.shape
        cell = self.static.cell_m
        path = np.zeros((h, w), bool)
        n = max(2, int(math.hypot(b[0] - a[0], b[1] - a[1]) / (cell / 2)))
        for t in np.linspace(0, 1, n):
            x, y = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
            path[h - 1 - math.floor(y / cell), math.floor(x / cell)] = True
        free = dilate(path, lane)
        self.true_static[free] = 0
        self.static.put(free, 0, 0.0, 0.0)

    def _clear_line(self, clear: np.ndarray, a, b) -> bool:
        h, cell = clear.shape[0], self.static.cell_m
        n = max(2, int(math.hypot(b[0] - a[0], b[1] - a[1]) / (cell / 2)))
        for t in np.linspace(0, 1, n):
            x, y = a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])
            if not clear[h - 1 - math.floor(y / cell), math.floor(x / cell)]:
                return False
        return True

    def advance(self, dt: float, user_xy: tuple[float, float]) -> None:
        """Everyone walks ``dt`` seconds on, unless the step would bring them within
        ``keep_m`` of the user; one who has waited ``patience_s`` turns back."""
        for p in self.people:
            if not self._step(p, dt, user_xy):
                p.waited += dt
                if p.waited >= self.patience_s:
                    p.turn_back()
                    p.waited = 0.0
                    self._step(p, dt, user_xy)
            else:
                p.waited = 0.0

    def _step(self, p: Person, dt: float, user_xy: tuple[float, float]) -> bool:
        x, y = p.where(p.s + p.speed * dt)
        if math.hypot(x - user_xy[0], y - user_xy[1]) < self.keep_m + RADIUS_M:
            return False
        p.s += p.speed * dt
        return True

    def stamp(self, true: np.ndarray) -> None:
        """Draw the people where they are now into ``self.scene`` and ``true`` (in place),
        first putting back what was under them before."""
        for rr, cc in self._cells:
            self.scene.z_lo[rr, cc] = self.static.z_lo[rr, cc]
            self.scene.z_hi[rr, cc] = self.static.z_hi[rr, cc]
            self.scene.kind[rr, cc] = self.static.kind[rr, cc]
            true[rr, cc] = self.true_static[rr, cc]
        self._cells = []
        h, w = true.shape
        cell = self.static.cell_m
        for p in self.people:
            x, y = p.where()
            c0, c1 = math.floor((x - RADIUS_M) / cell), math.floor((x + RADIUS_M) / cell)
            r0, r1 = (
                h - 1 - math.floor((y + RADIUS_M) / cell),
                h - 1 - math.floor((y - RADIUS_M) / cell),
            )
            rr, cc = np.mgrid[max(0, r0) : min(h, r1 + 1), max(0, c0) : min(w, c1 + 1)]
            cx, cy = (cc + 0.5) * cell, (h - rr - 0.5) * cell
            inside = np.hypot(cx - x, cy - y) <= RADIUS_M
            rr, cc = rr[inside], cc[inside]
            self.scene.put((rr, cc), PERSON, 0.0, HEIGHT_M)
            true[rr, cc] = 1
            self._cells.append((rr, cc))
