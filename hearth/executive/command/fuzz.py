"""A schema-driven fuzz of the HTTP API: requests generated from the app's own OpenAPI schema,
sent over a real socket; any 5xx answer is a failure.

Each request picks an operation, fills its path and query parameters and its JSON body from
their schemas (mostly valid values, some out of range, some of the wrong type, some junk),
with words the API knows mixed in (mission names, utterances, parameter names) so that
requests also get past the first checks. Some bodies are raw JSON no client library writes
(Infinity, NaN, 1e400, 5000-digit integers, lone surrogates, a key twice: ``HOSTILE_JSON``)
and some state-changing requests carry a foreign ``Origin`` (a page on another site): the
first must be 4xx, the second refused. The streaming endpoint (/api/events) is left out.

The values come from a seeded ``random.Random``: the same requests for the same seed, and
nothing beyond the standard library at run time, so ``hearth bench api`` runs without the
test extras. (hypothesis did the drawing before; its shrinking was never used here, since a
failure is reported with the request that caused it. Schemathesis does this job fully but
would be a heavy run-time dependency of a benchmark.)
"""
from __future__ import annotations

import math
import random
import string
from typing import Any
from urllib.parse import quote

_ALPHABET = string.printable + "\u00e9\u00df\u4e2d\U0001f600\x00\x7f"


def _text(rng: random.Random, lo: int = 0, hi: int = 20) -> str:
    return "".join(rng.choice(_ALPHABET) for _ in range(rng.randint(lo, max(lo, hi))))


def _float(rng: random.Random) -> float:
    return rng.choice([0.0, -0.0, 1.5, -1e308, 1e308, 5e-324, rng.uniform(-1e6, 1e6)])


def junk(rng: random.Random, depth: int = 0) -> Any:
    """Any JSON value (finite numbers), at most a few levels deep."""
    kinds = ["null", "bool", "int", "float", "text"] + (["list", "dict"] if depth < 3 else [])
    kind = rng.choice(kinds)
    if kind == "null":
        return None
    if kind == "bool":
        return rng.random() < 0.5
    if kind == "int":
        return rng.randint(-10**6, 10**6)
    if kind == "float":
        return _float(rng)
    if kind == "text":
        return _text(rng)
    if kind == "list":
        return [junk(rng, depth + 1) for _ in range(rng.randint(0, 4))]
    return {_text(rng, 0, 8): junk(rng, depth + 1) for _ in range(rng.randint(0, 4))}


def _resolve(schema: dict, root: dict) -> dict:
    while "$ref" in schema:
        name = schema["$ref"].split("/")[-1]
        schema = root["components"]["schemas"][name]
    return schema


def from_schema(rng: random.Random, schema: dict, root: dict, hints: list[str],
                depth: int = 0) -> Any:
    """A value for a JSON schema: mostly fitting it, sometimes not."""
    schema = _resolve(schema or {}, root)
    if "anyOf" in schema:
        return from_schema(rng, rng.choice(schema["anyOf"]), root, hints, depth + 1)
    t = schema.get("type")
    if t == "object" or "properties" in schema:
        props = schema.get("properties", {})
        if not props or rng.random() < 0.2:     # a free-form object, hints as keys
            keys = hints + [_text(rng, 0, 8)]
            return {rng.choice(keys): junk(rng) for _ in range(rng.randint(0, 3))}
        required = set(schema.get("required", []))
        out = {k: from_schema(rng, v, root, hints, depth + 1) for k, v in props.items()
               if k in required or rng.random() < 0.5}
        if rng.randint(0, 9) == 0:
            out[_text(rng, 0, 6)] = junk(rng)
        return out
    if t == "string":
        lo, hi = schema.get("minLength", 0), min(schema.get("maxLength", 40), 60)
        roll = rng.random()
        if roll < 0.25:
            return rng.choice(hints)
        if roll < 0.5:
            return _text(rng, lo, hi)
        if roll < 0.75:
            return _text(rng, 0, 300)
        return junk(rng)
    if t == "integer":
        lo = math.ceil(schema.get("minimum", -10**6))
        hi = math.floor(schema.get("maximum", 10**6))
        roll = rng.random()
        if roll < 0.66:
            return rng.randint(lo, hi)
        if roll < 0.83:
            return rng.choice([lo - 1, hi + 1, -2**63, 2**64, 0])
        return junk(rng)
    if t == "number":
        return _float(rng) if rng.random() < 0.5 else junk(rng)
    if t == "boolean":
        return rng.random() < 0.5 if rng.random() < 0.66 else junk(rng)
    if t == "array":
        return [from_schema(rng, schema.get("items", {}), root, hints, depth + 1)
                for _ in range(rng.randint(0, 3))]
    return junk(rng)


#: Raw JSON a client library would not send (issue 44): each made a 500 once.
HOSTILE_JSON = [b"Infinity", b"-Infinity", b"NaN", b"1e400", b"9" * 5000, b'"\\ud800"',
                b'"\\udfff x"', b'"a\\u0000b"']
#: Pages on other sites, as browsers name them in Origin (and Sec-Fetch-Site).
FOREIGN_ORIGINS = ["http://evil.example", "null", "https://127.0.0.1.evil.example"]


def hostile_body(rng: random.Random, body: Any) -> bytes:
    """``body`` as JSON text with one value replaced by a token of ``HOSTILE_JSON``, or with a
    key given twice."""
    import json
    text = json.dumps(body, separators=(",", ":"), default=repr)
    if isinstance(body, dict) and body and rng.random() < 0.3:
        k = rng.choice(list(body))
        return (text[:-1] + "," + json.dumps(k) + ":1}").encode()
    tok = rng.choice(HOSTILE_JSON).decode()
    if isinstance(body, dict) and body:
        k = rng.choice(list(body))
        return json.dumps({**body, k: "@@"}, default=repr).replace('"@@"', tok).encode()
    return tok.encode()


def operations(schema: dict) -> list[tuple[str, str, dict]]:
    ops = []
    for path, item in schema["paths"].items():
        if path == "/api/events":
            continue
        for method, op in item.items():
            if method in ("get", "post", "put", "delete", "patch"):
                ops.append((method.upper(), path, op))
    return ops


def make_request(rng: random.Random, schema: dict, hints: list[str]
                 ) -> tuple[str, str, dict, dict, Any]:
    """(method, url, query, headers, JSON body or None) for one random operation."""
    method, path, op = rng.choice(operations(schema))
    query, headers = {}, {}
    url = path
    for p in op.get("parameters", []):
        where, name = p["in"], p["name"]
        if where == "path":
            value = rng.choice(hints) if rng.random() < 0.5 else _text(rng, 1, 20)
            url = url.replace("{" + name + "}", quote(str(value), safe=""))
        elif rng.random() < 0.5:
            value = from_schema(rng, p.get("schema", {}), schema, hints)
            text = value if isinstance(value, str) else str(value)
            if where == "query":
                query[name] = text
            elif (where == "header" and text and text == text.strip() and text.isascii()
                  and text.isprintable()):
                headers[name] = text
    body = None
    rb = op.get("requestBody")
    if rb is not None:
        content = rb.get("content", {}).get("application/json", {})
        body = from_schema(rng, content.get("schema", {}), schema, hints)
        if rng.random() < 0.15:
            body = hostile_body(rng, body)      # raw bytes: sent as they are
    if method != "GET" and rng.random() < 0.1:
        headers["Origin"] = rng.choice(FOREIGN_ORIGINS)
    return method, url, query, headers, body


def run_fuzz(client: Any, schema: dict, hints: list[str], examples: int = 100,
             seed: int = 0) -> dict[str, Any]:
    """Send ``examples`` generated requests with ``client`` (an httpx.Client on the server);
    returns counts by status class and the failures: requests answered with 5xx, and
    state-changing requests from a foreign ``Origin`` that were not refused
    (``cross_site_accepted``). The same requests for the same ``seed``."""
    rng = random.Random(seed)
    counts: dict[str, int] = {}
    failures: list[dict[str, Any]] = []
    cross_site = 0
    for _ in range(examples):
        method, url, query, headers, body = make_request(rng, schema, hints)
        kw: dict[str, Any] = {"params": query, "headers": headers}
        if isinstance(body, bytes):
            kw["content"] = body
            kw["headers"] = {**headers, "content-type": "application/json"}
        elif body is not None:
            kw["json"] = body
        r = client.request(method, url, **kw)
        key = f"{r.status_code // 100}xx"
        counts[key] = counts.get(key, 0) + 1
        foreign = "Origin" in headers
        if r.status_code >= 500 or (foreign and r.status_code < 400):
            cross_site += foreign and r.status_code < 400
            failures.append({"method": method, "url": url, "query": query,
                             "body": body.decode("utf-8", "replace")[:300]
                             if isinstance(body, bytes) else body,
                             "headers": headers, "status": r.status_code,
                             "answer": r.text[:300]})
    return {"requests": sum(counts.values()), "by_class": counts, "failures": failures,
            "cross_site_accepted": cross_site}
