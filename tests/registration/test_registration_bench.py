"""The registration bench's localisation figures say what a mission would suffer."""
from __future__ import annotations

import numpy as np

import hearth.perception.localisation as localisation
from hearth.benchmarks import registration as bench


def test_a_trusted_fix_that_leaves_the_robot_off_counts_as_trusted_wrong(demo_world, monkeypatch):
    """A localiser that trusts whatever pose it was given (no correction at all) is wrong on
    every scene whose start error is over 2 cm: the bench reports those as trusted and
    wrong, not only as failures; a localiser that distrusts the same poses has none."""
    real = localisation.refine_localisation

    def trusting(world, depth, K, T_wc, T_wb, *args, trust=True, **kwargs):
        fix = real(world, depth, K, T_wc, T_wb, *args, **kwargs)
        fix.T_world_base, fix.ok = np.asarray(T_wb, dtype=float), trust
        fix.quality["loose"] = False
        return fix

    layout = bench.Layout.of(demo_world)
    figures = {}
    for trust in (True, False):
        monkeypatch.setattr(localisation, "refine_localisation",
                            lambda *a, trust=trust, **k: trusting(*a, trust=trust, **k))
        t = bench.Tally()
        bench.bench_localisation(demo_world, 3, np.random.default_rng(5), layout, t)
        figures[trust] = bench.figures(t)
    wrong = figures[True]["loc_failure_rate"]
    assert wrong > 0                      # start errors of up to 15 cm, left as they were
    assert figures[True]["loc_quality_ok_rate"] == 1.0
    assert figures[True]["loc_trusted_wrong_rate"] == wrong
    assert figures[False]["loc_failure_rate"] == wrong
    assert figures[False]["loc_trusted_wrong_rate"] == 0.0
    assert figures[True]["loc_loose_rate"] == figures[False]["loc_loose_rate"] == 0.0
