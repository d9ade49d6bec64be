"""People pacing their lanes: they keep clear of the user, wait, and give way."""

from __future__ import annotations

import math

from sim.courtyard import make_courtyard
from sim.people import RADIUS_M, Movers
from sim.scene3d import scene_from_scenario


def test_a_person_waits_for_the_user_then_turns_back():
    sc = make_courtyard(100, 0.2, 1)
    movers = Movers(scene_from_scenario(sc, 1), sc.true, sc.known, [sc.start, sc.goal], 3, 1)
    p = movers.people[0]
    p.s = 0.9  # on the way out, 0.9 m from their lane's end
    user = p.where(2.0)  # standing on the lane, 1.1 m ahead of them (lanes are 2-4 m)
    dist, still = [], 0
    for _ in range(30):
        before = p.where()
        movers.advance(0.5, user)
        still += p.where() == before
        dist.append(math.hypot(p.where()[0] - user[0], p.where()[1] - user[1]))
    assert min(dist) >= movers.keep_m + RADIUS_M - 1e-9  # never nearer than they keep
    assert still >= movers.patience_s / 0.5 - 1  # they waited ...
    assert max(dist) > min(dist) + 0.7  # ... then walked back the way they came
    # Had they not given up, they would stand there still.
    stubborn = Movers(scene_from_scenario(sc, 1), sc.true, sc.known, [sc.start, sc.goal], 3, 1,
                      patience_s=math.inf)  # fmt: skip
    stubborn.people[0].s = 0.9
    for _ in range(30):
        stubborn.advance(0.5, user)
    q = stubborn.people[0].where()
    assert math.hypot(q[0] - user[0], q[1] - user[1]) < movers.keep_m + RADIUS_M + 0.1
