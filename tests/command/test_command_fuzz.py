"""A bounded schema-driven fuzz of the API (executive/command/fuzz.py): no 5xx answers.
The larger run is in `hearth bench api` (fuzz_requests, fuzz_5xx)."""
from __future__ import annotations

HINTS = ["fetch_test", "wait_test", "oven_test", "rest_test", "where_test", "presence", "n",
         "object", "blue_cup", "bring me the cup", "turn off the oven", "a1", "a2", "home",
         "away", "", " ", "\u00e9", "../../etc/passwd", "%00"]


def test_fuzz_from_the_openapi_schema_finds_no_server_error(make_server):
    from executive.command.fuzz import run_fuzz
    srv = make_server(granted=1)
    schema = srv.client.get("/openapi.json").json()
    report = run_fuzz(srv.client, schema, HINTS, examples=150)
    assert report["failures"] == []
    assert report["requests"] == 150
    # The fuzz reaches past the first checks too: some requests succeed.
    assert report["by_class"].get("2xx", 0) > 10 and report["by_class"].get("4xx", 0) > 10
