"""The engines: the Ray engine gives the local engine's results, case by case; a scenario
that raises, kills its worker or hangs is reported and the others finish."""
from __future__ import annotations

from dataclasses import asdict

import pytest

import standins
from hearth.executive import suite, suite_bundles, suite_ray, suite_report, suite_worker
from hearth.executive.scenarios import Case, suite_cases


MESH_KNOBS = "home:4"     # a generated home whose oven knobs are mesh files


def test_a_world_travels_with_its_knob_meshes_and_loads_where_it_arrives(tmp_path):
    bundle = suite_bundles.world_bundle(MESH_KNOBS)
    knob_meshes = [name for name in bundle if name.startswith("meshes/knob-")]
    assert knob_meshes, sorted(bundle)
    world = suite_bundles.arrived_world(bundle, suite_bundles.bundle_fingerprint(bundle), tmp_path)
    assert world.knobs() and all((tmp_path / suite_bundles.bundle_fingerprint(bundle) / n).is_file()
                                 for n in knob_meshes)


def test_a_world_that_arrives_without_a_mesh_is_an_engine_error_kept_out_of_the_figures(
        tmp_path, ray_instance, monkeypatch):
    monkeypatch.setitem(suite_worker._WORKER, "worlds", {})     # nothing this process unpacked before
    bundle = suite_bundles.world_bundle(MESH_KNOBS)
    fp = suite_bundles.bundle_fingerprint(bundle)
    lost = dict(bundle)
    del lost[next(n for n in bundle if n.startswith("meshes/knob-"))]
    with pytest.raises(suite.SuiteError, match="contents differ"):
        suite_bundles.arrived_world(lost, fp, tmp_path)
    # the same loss on a Ray worker: an engine error, not a mission's failure
    import ray
    case = suite_cases(1, missions=("refine_localisation",), worlds=(MESH_KNOBS,))[0]
    task = ray.remote(suite_ray._ray_case).remote(asdict(case), suite.case_key(case), None, 60.0,
                                              fp, lost)
    res = ray.get(task)
    assert res["error"] == "engine" and "did not arrive whole" in res["reason"]
    from hearth.executive.scenarios import summarise
    from hearth.benchmarks.missions import incomplete
    summary = summarise([res])
    assert summary["engine_errors"][0]["world"] == MESH_KNOBS
    assert "refine_localisation" not in summary          # no mission figure from it
    assert "could not deliver 1 case" in incomplete(
        {"errors_by_kind": {"engine": 1}, **summary})


def six_cases() -> list[Case]:
    """Two scenarios of each named mission: the oven on the demo home (its knob models are
    what `make models` trains), localisation and a fetch on a generated home whose knobs are
    meshes (home 4: the world must travel with its mesh files)."""
    oven = suite_cases(2, missions=("turn_off_oven",), worlds=("demo",))
    home = suite_cases(2, missions=("refine_localisation",), worlds=(MESH_KNOBS,))
    fetch = suite_cases(1, missions=("fetch_object",), worlds=(MESH_KNOBS,), warmup=5,
                        fetch_every_type=False)
    cases = oven[:2] + home[:2] + fetch[:2]
    assert len(cases) == 6 and len({suite.case_key(c) for c in cases}) == 6
    return cases


def run(engine, cases) -> list[dict]:
    got = suite.run_cases(cases, engine)
    return [got[suite.case_key(c)] for c in cases]


# a hang guard, not a speed test: six scenarios run twice take 50 s on an idle 2-core
# machine and passed the suite's 300 s beside a 2-worker benchmark
@pytest.mark.timeout(900)
def test_ray_engine_gives_every_scenario_the_local_engines_result(ray_instance):
    cases = six_cases()
    local = run(suite.LocalEngine(jobs=2), cases)
    # Shipping the code as a cluster would get it: the tasks run from a copy, not this tree.
    on_ray = run(suite.RayEngine(ship_code=True), cases)
    assert [r["outcome"] for r in local] == [r["outcome"] for r in on_ray], \
        [(r.get("error"), r["reason"]) for r in local + on_ray]
    assert not any(r.get("error") for r in local + on_ray), [r["reason"] for r in on_ray]
    for a, b in zip(local, on_ray):
        assert suite_worker.comparable(a) == suite_worker.comparable(b), (a["key"], a["mission"])
    assert {r["engine"] for r in on_ray} == {"ray"}
    shipped = {r["code"] for r in on_ray}
    assert all("hearth-code-" in p for p in shipped), shipped


def misbehaving_cases() -> list[Case]:
    real = suite_cases(2, missions=("refine_localisation",), worlds=("demo",))[:2]
    odd = [Case("refine_localisation", 90 + i, world="demo", params={"standin": what})
           for i, what in enumerate(("raise", "exit", "hang"))]
    return [odd[0], real[0], odd[1], odd[2], real[1]]


def check_misbehaving(results: dict, cases: list[Case]) -> dict:
    by = {c.params.get("standin", "real"): results[suite.case_key(c)] for c in cases
          if c.params.get("standin")}
    assert len(results) == len(cases)
    assert by["raise"]["error"] == "exception"
    assert "forced crash of a stand-in scenario" in by["raise"]["traceback"]
    assert by["raise"]["reason"] == "RuntimeError: forced crash of a stand-in scenario"
    assert by["exit"]["error"] == "crashed" and by["exit"]["outcome"] == "error"
    assert by["hang"]["error"] == "timeout"
    assert "standins.py" in by["hang"]["traceback"], by["hang"]["traceback"]
    real = [results[suite.case_key(c)] for c in cases if not c.params]
    assert [r["outcome"] for r in real] == ["succeeded", "succeeded"], [r["reason"] for r in real]
    rep = suite_report.report(list(results.values()), cases)
    assert rep["problem_counts"] == {"exception": 1, "crashed": 1, "timeout": 1}
    text = suite_report.render_text(rep)
    assert "forced crash of a stand-in scenario" in text and "timed out after 15 s" in text
    return by


def test_local_engine_reports_a_crash_an_exit_and_hangs_and_finishes_the_others():
    cases = misbehaving_cases()
    cases.append(Case("refine_localisation", 99, world="demo", params={"standin": "stubborn"}))
    results = suite.run_cases(cases, suite.LocalEngine(jobs=2, timeout=15.0,
                                                       runner=standins.run))
    stubborn = results[suite.case_key(cases[-1])]
    assert stubborn["error"] == "timeout" and "was killed" in stubborn["reason"]
    del results[suite.case_key(cases[-1])]
    by = check_misbehaving(results, cases[:-1])
    assert "exit status 3" in by["exit"]["reason"]


def test_ray_engine_reports_a_crash_an_exit_and_a_hang_and_finishes_the_others(ray_instance):
    cases = misbehaving_cases()
    results = suite.run_cases(cases, suite.RayEngine(timeout=15.0, runner=standins.run))
    by = check_misbehaving(results, cases)
    assert "Ray worker died" in by["exit"]["reason"]


def test_ray_engine_without_ray_says_in_one_line_what_to_install(monkeypatch, capsys):
    import sys

    from hearth.cli.main import main
    monkeypatch.setitem(sys.modules, "ray", None)      # as if it were not installed
    with pytest.raises(suite.SuiteError, match=r"pip install 'hearth\[ray\]'"):
        suite.make_engine("ray")
    assert main(["suite", "--engine", "ray", "--homes", "0", "--out", "unused"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [suite_worker.RAY_MISSING]
