"""A schema-driven fuzz of the HTTP API: requests generated (hypothesis) from the app's own
OpenAPI schema, sent over a real socket; any 5xx answer is a failure.

Each request picks an operation, fills its path and query parameters and its JSON body from
their schemas (mostly valid values, some out of range, some of the wrong type, some junk),
with words the API knows mixed in (mission names, utterances, parameter names) so that
requests also get past the first checks. The streaming endpoint (/api/events) is left out.
"""
from __future__ import annotations

from typing import Any
from urllib.parse import quote

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

JSON = st.recursive(st.none() | st.booleans() | st.integers(-10**6, 10**6)
                    | st.floats(allow_nan=False, allow_infinity=False) | st.text(max_size=20),
                    lambda kids: st.lists(kids, max_size=4)
                    | st.dictionaries(st.text(max_size=8), kids, max_size=4),
                    max_leaves=8)


def _resolve(schema: dict, root: dict) -> dict:
    while "$ref" in schema:
        name = schema["$ref"].split("/")[-1]
        schema = root["components"]["schemas"][name]
    return schema


def from_schema(schema: dict, root: dict, hints: list[str], depth: int = 0) -> st.SearchStrategy:
    """Values for a JSON schema: mostly fitting it, sometimes not."""
    schema = _resolve(schema or {}, root)
    junk = JSON
    if "anyOf" in schema:
        return st.one_of([from_schema(s, root, hints, depth + 1) for s in schema["anyOf"]])
    t = schema.get("type")
    if t == "object" or "properties" in schema:
        props = schema.get("properties", {})
        required = set(schema.get("required", []))
        fields = {k: from_schema(v, root, hints, depth + 1) for k, v in props.items()}

        @st.composite
        def obj(draw):
            out = {}
            for k, strat in fields.items():
                if k in required or draw(st.booleans()):
                    out[k] = draw(strat)
            if draw(st.integers(0, 9)) == 0:
                out[draw(st.text(max_size=6))] = draw(junk)
            return out
        extra = st.dictionaries(st.sampled_from(hints) | st.text(max_size=8), junk, max_size=3)
        return st.one_of(obj(), extra) if props else extra
    if t == "string":
        lo, hi = schema.get("minLength", 0), min(schema.get("maxLength", 40), 60)
        good = st.sampled_from(hints) | st.text(min_size=lo, max_size=hi)
        return st.one_of(good, good, st.text(max_size=300), junk)
    if t == "integer":
        lo, hi = schema.get("minimum", -10**6), schema.get("maximum", 10**6)
        return st.one_of(st.integers(lo, hi), st.integers(lo, hi), st.integers(), junk)
    if t == "number":
        return st.one_of(st.floats(allow_nan=False), junk)
    if t == "boolean":
        return st.one_of(st.booleans(), st.booleans(), junk)
    if t == "array":
        return st.lists(from_schema(schema.get("items", {}), root, hints, depth + 1), max_size=3)
    return junk


def operations(schema: dict) -> list[tuple[str, str, dict]]:
    ops = []
    for path, item in schema["paths"].items():
        if path == "/api/events":
            continue
        for method, op in item.items():
            if method in ("get", "post", "put", "delete", "patch"):
                ops.append((method.upper(), path, op))
    return ops


def request_strategy(schema: dict, hints: list[str]) -> st.SearchStrategy:
    ops = operations(schema)

    @st.composite
    def request(draw):
        method, path, op = draw(st.sampled_from(ops))
        query, headers = {}, {}
        url = path
        for p in op.get("parameters", []):
            where, name = p["in"], p["name"]
            if where == "path":
                value = draw(st.sampled_from(hints) | st.text(min_size=1, max_size=20))
                url = url.replace("{" + name + "}", quote(str(value), safe=""))
            elif draw(st.booleans()):
                value = draw(from_schema(p.get("schema", {}), schema, hints))
                text = value if isinstance(value, str) else str(value)
                if where == "query":
                    query[name] = text
                elif where == "header" and text and text == text.strip() and text.isascii() and text.isprintable():
                    headers[name] = text
        body = None
        rb = op.get("requestBody")
        if rb is not None:
            content = rb.get("content", {}).get("application/json", {})
            body = draw(from_schema(content.get("schema", {}), schema, hints))
        return method, url, query, headers, body
    return request()


def run_fuzz(client: Any, schema: dict, hints: list[str], examples: int = 100) -> dict[str, Any]:
    """Send ``examples`` generated requests with ``client`` (an httpx.Client on the server);
    returns counts by status class and the requests answered with 5xx. Derandomised: the
    same requests every run."""
    counts: dict[str, int] = {}
    failures: list[dict[str, Any]] = []

    @settings(max_examples=examples, deadline=None, database=None, derandomize=True,
              suppress_health_check=list(HealthCheck))
    @given(request_strategy(schema, hints))
    def one(req):
        method, url, query, headers, body = req
        kw = {"params": query, "headers": headers}
        if body is not None:
            kw["json"] = body
        r = client.request(method, url, **kw)
        key = f"{r.status_code // 100}xx"
        counts[key] = counts.get(key, 0) + 1
        if r.status_code >= 500:
            failures.append({"method": method, "url": url, "query": query, "body": body,
                             "status": r.status_code, "answer": r.text[:300]})
    one()
    return {"requests": sum(counts.values()), "by_class": counts, "failures": failures}
