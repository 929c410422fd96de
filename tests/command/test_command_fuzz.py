"""A bounded schema-driven fuzz of the API (hearth/executive/command/fuzz.py): no 5xx answers.
The larger run is in `hearth bench api` (fuzz_requests, fuzz_5xx)."""
from __future__ import annotations

HINTS = ["fetch_test", "wait_test", "oven_test", "rest_test", "where_test", "presence", "n",
         "object", "blue_cup", "bring me the cup", "turn off the oven", "a1", "a2", "home",
         "away", "", " ", "\u00e9", "../../etc/passwd", "%00"]


def test_fuzz_from_the_openapi_schema_finds_no_server_error(make_server):
    from hearth.executive.command.fuzz import run_fuzz
    srv = make_server(granted=1)
    schema = srv.client.get("/openapi.json").json()
    report = run_fuzz(srv.client, schema, HINTS, examples=150)
    assert report["failures"] == [] and report["cross_site_accepted"] == 0
    assert report["requests"] == 150
    # The fuzz reaches past the first checks too: some requests succeed.
    assert report["by_class"].get("2xx", 0) > 10 and report["by_class"].get("4xx", 0) > 10


def test_the_fuzz_and_the_api_benchmark_need_no_test_extras():
    # `hearth bench api` runs on an install without the dev extra: hypothesis is not
    # imported by shipped code (httpx is the `http` extra, imported when the clients run).
    import subprocess
    import sys
    code = ("import sys; sys.modules['hypothesis'] = None; sys.modules['httpx'] = None; "
            "import hearth.executive.command.fuzz, hearth.executive.command.api, hearth.benchmarks.api")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_the_fuzz_sends_the_same_requests_for_the_same_seed(make_server):
    import random
    from hearth.executive.command.fuzz import make_request
    srv = make_server()
    schema = srv.client.get("/openapi.json").json()
    def draws(seed):
        rng = random.Random(seed)
        return [make_request(rng, schema, HINTS) for _ in range(20)]
    assert draws(7) == draws(7)
    assert draws(7) != draws(8)
