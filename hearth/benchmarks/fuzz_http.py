"""Hostile requests to a real HTTP server over the demo home (issue 44; ``check_http``): the
hand-made ones by class with the answer each must get, and schema-generated ones
(hearth/executive/command/fuzz.py)."""
from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from hearth.benchmarks.fuzz_generate import WORST_UTTERANCE


# ---------------------------------------------------------------------------------------------
# The HTTP API (issue 44): hostile requests to a real server

_WORST_MISSION = ("hearth: 1\nname: worst\nutterances: ['" + "(x) " * 60 + "go']\n"
                  "tree:\n  skill: Act\n")


def _http_cases(port: int, run_id: str) -> list[tuple[str, str, str, str, dict, bytes, int]]:
    """(class, name, method, path, headers, body, expected status) of the hand-made requests."""
    js = {"content-type": "application/json"}
    out = []
    for origin in ("http://evil.com", "null", f"http://127.0.0.1:{port + 1}"):
        for method, path in (("POST", "/api/stop"), ("POST", f"/api/runs/{run_id}/cancel"),
                             ("POST", "/api/runs"), ("PUT", "/api/autonomy")):
            body = b'{"mission": "bench_chores"}' if path == "/api/runs" else \
                b'{"level": 3}' if path == "/api/autonomy" else b""
            out.append(("cross-site", f"{method} {path} from {origin}", method, path,
                        {"Origin": origin, **js}, body, 403))
    out.append(("cross-site", "POST /api/stop with Sec-Fetch-Site: cross-site", "POST",
                "/api/stop", {"Sec-Fetch-Site": "cross-site"}, b"", 403))
    for host in ("localhost:80@evil.com", f"localhost:{port}@evil.com", "localhost:99999",
                 f"127.0.0.1:{port + 1}", "a b", "localhost, evil.com"):
        out.append(("host", f"Host {host}", "GET", "/api/health", {"Host": host}, b"", 421))
    for name, value in (("infinity", b"Infinity"), ("nan", b"NaN"), ("1e400", b"1e400"),
                        ("5000_digits", b"9" * 5000)):
        out.append(("huge-integer" if "digit" in name else "numbers", f"priority {name}",
                    "POST", "/api/runs", js, b'{"mission":"bench_chores","priority":' + value
                    + b"}", 422))
    out.append(("nul", "parameter value with NUL and a lone surrogate", "PUT",
                "/api/parameters/presence", js, b'{"value":"\\u0000\\ud800"}', 422))
    out.append(("structure", "a key twice", "POST", "/api/runs", js,
                b'{"mission":"bench_chores","mission":"worst"}', 422))
    out.append(("template", "the worst template's utterance", "POST", "/api/commands", js,
                ('{"text": "%s"}' % WORST_UTTERANCE).encode(), 200))
    return out


def check_http(n: int, seed: int) -> dict:
    """The hand-made hostile requests and ``n`` schema-generated ones (with hostile bodies and
    foreign origins) against a real server over the demo home; health asked while the worst
    template is matched. Failures: a 5xx, an answer other than the expected one, a foreign
    page's state change accepted."""
    import threading

    import httpx

    from hearth.executive.command.api import create_app
    from hearth.executive.command.fuzz import run_fuzz
    from hearth.executive.command.server import ServerThread
    from hearth.benchmarks.api import _service
    from hearth.robot.clock import SimClock

    report: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "worst.yaml").write_text(_WORST_MISSION)
        service, _ = _service(tmp, SimClock(), 10.0)
        try:
            with ServerThread(create_app(service)) as srv, \
                    httpx.Client(base_url=srv.url, timeout=60.0) as c:
                run_id = c.post("/api/runs", json={"mission": "bench_chores"}).json()["run"]["id"]
                by_class: dict[str, dict[str, int]] = {}
                failures = []
                for klass, name, method, path, headers, body, expect in _http_cases(
                        srv.port, run_id):
                    r = c.request(method, path, headers=headers, content=body)
                    row = by_class.setdefault(klass, {"requests": 0, "failures": 0})
                    row["requests"] += 1
                    if r.status_code != expect:
                        row["failures"] += 1
                        failures.append({"class": klass, "case": name, "status": r.status_code,
                                         "expected": expect, "answer": r.text[:200]})
                # health while the worst template is matched (figures, not a gate)
                t0 = time.perf_counter()
                done: dict[str, float] = {}

                def worst() -> None:
                    c.post("/api/commands", json={"text": WORST_UTTERANCE})
                    done["ms"] = (time.perf_counter() - t0) * 1000
                th = threading.Thread(target=worst)
                th.start()
                health = c.get("/api/health")
                health_ms = (time.perf_counter() - t0) * 1000
                th.join(120)
                schema = c.get("/openapi.json").json()
                fuzz = run_fuzz(c, schema, ["bench_chores", "worst", "presence", run_id,
                                            WORST_UTTERANCE, "x x go", ""], n, seed=seed)
        finally:
            service.executive.shutdown()
            service.close()
    fixed_5xx = sum(f["status"] >= 500 for f in failures)
    report.update(
        fixed_requests=sum(r["requests"] for r in by_class.values()), by_class=by_class,
        fixed_failures=failures[:20], generated_requests=fuzz["requests"],
        generated_by_status=fuzz["by_class"], generated_failures=fuzz["failures"][:20],
        cross_site_accepted=fuzz["cross_site_accepted"] + sum(
            f["status"] < 400 for f in failures if f["class"] == "cross-site"),
        **{"5xx": fixed_5xx + sum(f["status"] >= 500 for f in fuzz["failures"])},
        health_ok_during_worst_template=health.status_code == 200,
        health_ms_during_worst_template=round(health_ms, 1),
        worst_template_command_ms=round(done.get("ms", float("nan")), 1))
    report["failures"] = len(failures) + len(fuzz["failures"])
    return report
