"""The draft's large-object classifier (hearth/mapping/classify.py): its second stage reads
the room around an object, as Rusu's CRF reads the neighbours."""
from __future__ import annotations

import numpy as np

from hearth.mapping.classify import LargeObjectClassifier


def _homes(n: int, rng) -> tuple[list, list, list]:
    """Homes of two rooms: a kitchen (an oven and a carcass: a cupboard) and a living room
    (a coffee table and the same carcass: a sideboard). The carcasses' own features are
    drawn from one distribution, so only the room tells them apart."""
    X, y, rooms = [], [], []
    for h in range(n):
        for room, (other, carcass) in enumerate((("oven", "cupboard"), ("table", "sideboard"))):
            centre = {"oven": 3.0, "table": -3.0}[other]
            X.append([centre + rng.normal(0, 0.1), rng.normal(0, 0.1)])
            y.append(other)
            X.append([rng.normal(0, 0.1), rng.normal(0, 0.1)])
            y.append(carcass)
            rooms += [(h, room)] * 2
    return X, y, rooms


def test_the_same_carcass_is_a_cupboard_beside_an_oven_and_a_sideboard_beside_a_table():
    rng = np.random.default_rng(0)
    X, y, rooms = _homes(12, rng)
    clf = LargeObjectClassifier(n_estimators=50).fit(X, y, rooms=rooms)
    Xt, yt, rooms_t = _homes(4, rng)
    # one home's objects: the rooms are named by anything hashable
    pred = clf.predict(Xt, rooms=[r[0] * 10 + r[1] for r in rooms_t])
    assert list(pred) == yt
    # without the rooms the carcasses cannot be told apart: the first stage guesses
    alone = clf.predict(Xt)
    carcass = [i for i, t in enumerate(yt) if t in ("cupboard", "sideboard")]
    assert sum(alone[i] == yt[i] for i in carcass) < len(carcass)
