"""The monitor page in headless Chromium, as an operator uses it: approve a step, cancel a
run and stop everything from the page, set a runtime parameter, read progress that
rewrites its own line, reload and find the same state, see a for_each's items fresh, and a
layout that works at 800 and 1400 px (positions asserted in the page; screenshots kept).

Needs Debian's Chromium at /usr/bin/chromium: ``make test`` installs it (scripts/sysdeps.sh)
when run as root; otherwise these tests are skipped and say which command installs it.
Chromium is driven through the DevTools protocol over a WebSocket (the ``websockets``
client of the dev extra). Set HEARTH_SCREENSHOTS=DIR to keep the screenshots in DIR.
"""
from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import threading
import urllib.request
from contextlib import ExitStack
from pathlib import Path

import httpx
import pytest
from py_trees import common
from websockets.sync.client import connect

from hearth.executive.command.api import create_app
from hearth.executive.command.server import ServerThread, make_service
from hearth.executive.testing import Script, ScriptedSkill, Substitution, test_skills
from hearth.robot.clock import WallClock
from hearth.skills.base import Port

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--hide-scrollbars=false",
         "--remote-debugging-address=127.0.0.1", "--remote-debugging-port=0"]
HERE = Path(__file__).parent

pytestmark = pytest.mark.skipif(
    not os.path.exists(CHROMIUM),
    reason=f"{CHROMIUM} is missing: `make test` installs it when run as root; otherwise run "
           "as root: apt-get update && apt-get install -y chromium chromium-driver")


# -- the browser ------------------------------------------------------------------------------
class Page:
    """One Chromium tab over the DevTools protocol."""

    def __init__(self, ws_url: str):
        self._closing = ExitStack()
        self.ws = self._closing.enter_context(connect(ws_url, max_size=None, open_timeout=60))
        self.next_id = 0

    def call(self, method: str, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv(timeout=120))
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(msg["error"])
                return msg["result"]

    def js(self, expression: str):
        """The value of ``expression`` in the page (JSON-able)."""
        res = self.call("Runtime.evaluate", expression=expression, returnByValue=True,
                        awaitPromise=True)
        if "exceptionDetails" in res:
            raise RuntimeError(res["exceptionDetails"])
        return res["result"].get("value")

    def wait_for(self, expression: str, want, limit_ms: int = 30000):
        """Evaluate ``expression`` in the page until it equals ``want`` (or the limit, in the
        browser's time, runs out); returns its last value."""
        js = f"""new Promise(resolve => {{
            const t0 = Date.now();
            (function check() {{
                let v; try {{ v = ({expression}); }} catch (e) {{ v = "error: " + e; }}
                if (JSON.stringify(v) === {json.dumps(json.dumps(want, separators=(",", ":")))}
                    || Date.now() - t0 > {limit_ms}) resolve(v);
                else setTimeout(check, 25);
            }})();
        }})"""
        for _ in range(50):   # the page may still be navigating
            try:
                return self.js(js)
            except RuntimeError as err:
                if "context" not in str(err) and "navigat" not in str(err):
                    raise
        raise RuntimeError("the page never settled")

    def click(self, selector: str) -> None:
        assert self.wait_for(f"document.querySelector({json.dumps(selector)}) !== null", True), selector
        self.js(f"document.querySelector({json.dumps(selector)}).click()")

    def viewport(self, width: int, height: int) -> None:
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height,
                  deviceScaleFactor=1, mobile=False)

    def open(self, url: str) -> None:
        self.call("Page.navigate", url=url)
        assert self.wait_for('document.body && document.body.getAttribute("data-live")', "1") == "1"

    def reload(self) -> None:
        self.js('document.body.removeAttribute("data-live")')
        self.call("Page.reload", ignoreCache=True)
        assert self.wait_for('document.body && document.body.getAttribute("data-live")', "1") == "1"

    def screenshot(self, path: Path) -> Path:
        shot = self.call("Page.captureScreenshot", format="png")
        path.write_bytes(base64.b64decode(shot["data"]))
        keep = os.environ.get("HEARTH_SCREENSHOTS")
        if keep:
            Path(keep).mkdir(parents=True, exist_ok=True)
            shutil.copy(path, Path(keep) / path.name)
        return path

    def close(self) -> None:
        self._closing.close()


@pytest.fixture
def chromium(tmp_path):
    procs = []
    pages = []

    def launch(url: str | None = None, width: int = 1400, height: int = 900) -> Page:
        profile = tmp_path / f"profile{len(procs)}"
        proc = subprocess.Popen([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(proc)
        port_file = profile / "DevToolsActivePort"
        # Chromium writes the port once it listens; waiting on the file is start-up, bounded.
        for _ in range(600):
            if port_file.exists() and port_file.read_text().strip():
                break
            if proc.poll() is not None:
                pytest.fail(f"chromium exited with {proc.returncode}")
            threading.Event().wait(0.1)
        port = int(port_file.read_text().split()[0])
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
        page = Page(next(t for t in targets if t["type"] == "page")["webSocketDebuggerUrl"])
        pages.append(page)
        page.viewport(width, height)
        if url:
            page.open(url)
        return page
    yield launch
    for page in pages:
        page.close()
    for p in procs:
        p.terminate()
        p.wait(10)


# -- a server with the page's test missions ---------------------------------------------------
class Creep(ScriptedSkill):
    """A test-only drive whose feedback counts up in per cent, as the robot's actions do."""
    NAME = "Creep"
    AUTONOMY = 1
    script = Script(duration=40.0)

    def update(self):
        done = (self._now() - self._started) / self.script.duration
        if done < 1.0:
            self.feedback_message = f"creeping: {done:.0%}"
            return common.Status.RUNNING
        self.feedback_message = "creeping: done"
        return common.Status.SUCCESS


class Gauge(ScriptedSkill):
    """A test-only check that reports a sentence and its values (Skill.report), as the
    registration skills do."""
    NAME = "Gauge"

    def update(self):
        self.report("fix on fridge not trusted: too weak (fitness 0.31); pose left unchanged",
                    fitness=0.3123, rmse_mm=4.1, landmarks=["fridge", "oven"], converged=False)
        return common.Status.SUCCESS


class TurnTestKnob(ScriptedSkill):
    """A test-only step that acts on the home (autonomy 2): it asks when 1 is granted (the
    command tests' oven_test uses it too)."""
    NAME = "TurnTestKnob"
    AUTONOMY = 2
    INPUTS = (Port("knob", "node_id"),)


def big_mission(path: Path, depth: int = 12, leaves: int = 12) -> Path:
    """A mission whose tree is ~3,500 px tall: ``depth`` nested sequences with ``leaves``
    steps each (long names, as real missions have), then a step that needs approval."""
    lines = ["hearth: 1", "name: big_test", "description: A tall tree (the page's layout test).",
             "tree:", "  sequence:"]

    def level(d: int, indent: str) -> None:
        for i in range(leaves):
            lines.append(f"{indent}- skill: Act")
            lines.append(f"{indent}  name: look_at_landmark_number_{d}_{i}_and_refine")
        if d + 1 < depth:
            lines.append(f"{indent}- sequence:")
            level(d + 1, indent + "    ")
            lines.append(f"{indent}  name: search_known_places_level_{d + 1}")
    level(0, "    ")
    lines += ["    - skill: TurnTestKnob", "      name: turn_the_knob",
              "      inputs: {knob: oven}"]
    path.write_text("\n".join(lines) + "\n")
    return path


class MonitorServer:
    """The API on 127.0.0.1 over an executive of scripted skills ticking at 50 Hz on a wall
    clock, with the command tests' missions and the page's own."""

    def __init__(self, world, tmp_path: Path, granted: int = 3):
        scripts = [
            Script(match="/wait_test/hold", duration=3600.0),
            # each_test: item 1 looks then fails to verify, item 2 likewise, item 3 fails to
            # look (so "verify" is not ticked for it); then "hold" runs for an hour.
            Script(match="/each_test/*/look", duration=0.3, outcomes=["success", "success", "failure"]),
            Script(match="/each_test/*/verify", outcomes=["failure"], feedback="not the right place"),
            Script(match="/each_test/hold", duration=3600.0),
            Script(match="/report_test/hold", duration=3600.0),
        ]
        skills = test_skills()
        skills.update({c.NAME: c for c in (Creep, TurnTestKnob, Gauge)})
        missions = [str(HERE / "missions"), str(HERE / "monitor_missions"),
                    str(big_mission(tmp_path / "big_test.yaml"))]
        self.service = make_service(world, None, missions, skills=skills,
                                    make_skill=Substitution(scripts, None), clock=WallClock(),
                                    tick_hz=50, runs_dir=None, granted=granted)
        assert self.service.catalogue_problems == []
        self.thread = ServerThread(create_app(self.service)).start()
        self.url = self.thread.url
        self.client = httpx.Client(base_url=self.url, timeout=30.0)

    def submit(self, mission: str, **params) -> str:
        r = self.client.post("/api/runs", json={"mission": mission, "params": params})
        assert r.status_code == 201, r.text
        return r.json()["run"]["id"]

    def status(self, run_id: str) -> str:
        return self.client.get(f"/api/runs/{run_id}").json()["status"]

    def wait_ended(self, run_id: str) -> str:
        with self.client.stream("GET", "/api/events", params={"run": run_id, "since": 0,
                                                              "close_on_end": True}) as r:
            for _ in r.iter_lines():
                pass
        return self.status(run_id)

    def close(self) -> None:
        self.client.close()
        self.thread.stop()
        self.service.executive.shutdown()
        self.service.close()


@pytest.fixture
def monitor(demo_world, tmp_path):
    made = []

    def make(**kw) -> MonitorServer:
        made.append(MonitorServer(demo_world, tmp_path, **kw))
        return made[-1]
    yield make
    for s in made:
        s.close()


def node_status(path: str) -> str:
    return f'document.querySelector(\'li.node[data-path="{path}"]\')?.getAttribute("data-status")'


def node_text(path: str) -> str:
    return f'document.querySelector(\'li.node[data-path="{path}"] > .row .fb\')?.textContent'


TEXT = 'document.getElementById("{}").textContent'
LOG_LINES_OF = 'Array.from(document.querySelectorAll(\'#feedback li[data-path="{}"] .msg\')).map(e => e.textContent)'


# -- the tests ----------------------------------------------------------------------------------
def test_monitor_page_shows_a_node_change_state(make_server, chromium):
    srv = make_server(granted=1)
    # The knob step waits for an operator's approval: RUNNING until someone decides.
    run_id = srv.client.post("/api/runs", json={"mission": "oven_test"}).json()["run"]["id"]
    events = list(srv.events(run=run_id, close_on_end=False,
                             until=lambda k, d: k == "approval" and d["state"] == "pending"))
    pending = events[-1][1]["id"]
    page = chromium(srv.url + "/")
    node = node_status("/oven_test/turn")
    assert page.wait_for(node, "RUNNING") == "RUNNING"
    assert page.wait_for(TEXT.format("run-id"), run_id) == run_id
    # The page lists the pending approval; approving it there lets the skill run.
    button = f'[data-request="{pending}"] [data-action="approve"]'
    page.click(button)
    assert page.wait_for(node, "SUCCESS") == "SUCCESS"
    assert page.wait_for(TEXT.format("run-status"), "succeeded") == "succeeded"
    assert srv.client.get(f"/api/runs/{run_id}").json()["status"] == "succeeded"
    # A run started after the page loaded replaces the tree as it starts.
    second = srv.client.post("/api/runs", json={"mission": "fetch_test",
                                                "params": {"object": "bowl"}}).json()["run"]["id"]
    assert page.wait_for(TEXT.format("run-id"), second) == second
    assert page.wait_for(node_status("/fetch_test/tell"), "SUCCESS") == "SUCCESS"


def test_cancel_from_the_page_ends_the_run_cancelled_and_progress_keeps_one_line(monitor, chromium):
    srv = monitor()
    run_id = srv.submit("long_test")
    page = chromium(srv.url + "/")
    assert page.wait_for(TEXT.format("run-id"), run_id) == run_id
    assert page.wait_for(node_status("/long_test/drive"), "RUNNING") == "RUNNING"
    # The drive reports 0 %, 1 %, 2 %, ...: one log line rewrites itself.
    lines = LOG_LINES_OF.format("/long_test/drive")
    assert page.wait_for(f"{lines}.length === 1 && /creeping: ([3-9]|\\d\\d)%/.test({lines}[0])", True)
    assert page.js(f"{lines}.length") == 1
    running = page.js('Array.from(document.querySelectorAll("#progress li")).map(li => li.textContent)')
    assert len(running) == 1 and running[0].startswith("drive (Creep)creeping: ")
    # Cancel on the page: the run is halted and ends cancelled, and the page says so.
    page.click("#cancel")
    assert page.wait_for(TEXT.format("run-status"), "cancelled") == "cancelled"
    assert srv.status(run_id) == "cancelled"
    assert "cancelled from the monitor page" in page.wait_for(
        f'{TEXT.format("run-reason")}.includes("monitor page") ? {TEXT.format("run-reason")} : ""',
        "cancelled from the monitor page")
    assert page.js('document.getElementById("cancel").disabled') is True
    assert page.js(node_status("/long_test/arrive")) == "INVALID"


def test_stop_all_cancels_the_queue_and_the_running_run(monitor, chromium):
    srv = monitor()
    first, second = srv.submit("long_test"), srv.submit("long_test")
    page = chromium(srv.url + "/")
    assert page.wait_for(TEXT.format("run-id"), first) == first
    assert srv.status(second) == "queued"
    queued = f'document.querySelector(\'#runs li[data-run="{second}"] .state\')?.textContent'
    assert page.wait_for(queued, "queued") == "queued"
    page.click("#stop")
    assert page.wait_for(TEXT.format("run-status"), "cancelled") == "cancelled"
    assert page.wait_for(queued, "cancelled") == "cancelled"
    assert (srv.status(first), srv.status(second)) == ("cancelled", "cancelled")
    assert page.wait_for(TEXT.format("run-notice"), "stopped: 2 runs cancelled") == \
        "stopped: 2 runs cancelled"
    # Nothing was left to start.
    assert srv.client.get("/api/health").json()["queued"] == []


def test_runtime_parameter_is_set_from_the_page(monitor, chromium):
    srv = monitor()
    run_id = srv.submit("long_test", presence="away")
    page = chromium(srv.url + "/")
    assert page.wait_for(TEXT.format("run-id"), run_id) == run_id
    select = '#params [data-param="presence"] select'
    # The mission's runtime parameter, with its enum as the choices and the run's own value
    # (given at submit; the value the next run would get is still the default).
    assert page.wait_for(f'Array.from(document.querySelectorAll(\'{select} option\')).map(o => o.textContent)',
                         ["home", "away"]) == ["home", "away"]
    assert page.js(f'JSON.parse(document.querySelector(\'{select}\').value)') == "away"
    assert srv.client.get("/api/parameters").json()["presence"]["value"] == "home"
    choose = (f'(v => {{ const s = document.querySelector(\'{select}\'); s.value = JSON.stringify(v); '
              f's.dispatchEvent(new Event("change")); }})')
    said = 'Array.from(document.querySelectorAll("#feedback li .msg")).some(m => m.textContent === "presence set to {}")'
    for value in ("home", "away"):
        page.js(f"{choose}({json.dumps(value)})")
        # the running mission got it (its param event is in the log) and the page shows it
        assert page.wait_for(said.format(value), True)
        assert page.wait_for(f'JSON.parse(document.querySelector(\'{select}\').value)', value) == value
    assert srv.client.get("/api/parameters").json()["presence"]["value"] == "away"
    srv.client.post(f"/api/runs/{run_id}/cancel")


def _each_state(page):
    base = "/each_test/force_success/for_each"
    return {"for_each": page.js(node_text(base)),
            "look": page.js(node_status(f"{base}/sequence/look")),
            "verify": page.js(node_status(f"{base}/sequence/verify")),
            "verify_text": page.js(node_text(f"{base}/sequence/verify")),
            "hold": page.js(node_status("/each_test/hold"))}


def test_for_each_items_are_shown_fresh_and_the_state_survives_a_reload(monitor, chromium):
    srv = monitor()
    page = chromium(srv.url + "/")
    run_id = srv.submit("each_test")
    assert page.wait_for(TEXT.format("run-id"), run_id) == run_id
    assert page.wait_for(node_status("/each_test/hold"), "RUNNING") == "RUNNING"
    # Items 1 and 2 failed at "verify"; item 3 failed at "look", so "verify" did not run
    # for it: it shows idle and no text, not item 2's failure.
    want = {"for_each": "item 3: bedroom", "look": "FAILURE", "verify": "INVALID",
            "verify_text": "", "hold": "RUNNING"}
    assert _each_state(page) == want
    # (The server's tree still holds each node's last report: verify's is item 2's.)
    tree = srv.client.get(f"/api/runs/{run_id}/tree").json()
    verify = tree["root"]["children"][0]["children"][0]["children"][0]["children"][1]
    assert verify["status"] == "FAILURE"
    log = page.js('Array.from(document.querySelectorAll("#feedback li")).map(li => li.textContent)')
    assert any("item 3: bedroom" in line for line in log)
    assert any("not the right place" in line for line in log)
    # A reload shows the same run, tree, log and freshness (from the run's recent events).
    page.reload()
    assert page.wait_for(TEXT.format("run-id"), run_id) == run_id
    assert page.wait_for(TEXT.format("run-status"), "running") == "running"
    assert page.wait_for(node_status("/each_test/hold"), "RUNNING") == "RUNNING"
    assert _each_state(page) == want
    assert page.js('Array.from(document.querySelectorAll("#feedback li")).map(li => li.textContent)') == log
    srv.client.post(f"/api/runs/{run_id}/cancel")
    assert page.wait_for(TEXT.format("run-status"), "cancelled") == "cancelled"
    page.reload()
    assert page.wait_for(TEXT.format("run-status"), "cancelled") == "cancelled"
    assert page.js(TEXT.format("run-reason")) == "cancelled by a client"


VALUES_OF = ('Array.from(document.querySelectorAll(\'#feedback li[data-path="{}"] table.values tr\'))'
             '.map(tr => [tr.cells[0].textContent, tr.cells[1].textContent])')


def test_a_feedbacks_values_are_shown_as_a_table_under_its_sentence(monitor, chromium):
    srv = monitor()
    page = chromium(srv.url + "/")
    run_id = srv.submit("report_test")
    assert page.wait_for(node_status("/report_test/hold"), "RUNNING") == "RUNNING"
    sentence = "fix on fridge not trusted: too weak (fitness 0.31); pose left unchanged"
    assert page.wait_for(node_text("/report_test/check"), sentence) == sentence
    # The values the sentence does not say in these words, in words; none of them as JSON.
    rows = page.wait_for(VALUES_OF.format("/report_test/check"),
                         [["fitness", "0.312"], ["rmse mm", "4.1"], ["landmarks", "fridge, oven"],
                          ["converged", "no"]])
    assert rows == [["fitness", "0.312"], ["rmse mm", "4.1"], ["landmarks", "fridge, oven"],
                    ["converged", "no"]]
    assert page.js(LOG_LINES_OF.format("/report_test/check")) == [sentence]
    title = page.js('document.querySelector(\'li.node[data-path="/report_test/check"] > .row .fb\').title')
    assert title.splitlines() == [sentence, "fitness 0.312", "rmse mm 4.1", "landmarks fridge, oven",
                                  "converged no"]
    # The same after a reload (from the run's recent events and its tree).
    page.reload()
    assert page.wait_for(TEXT.format("run-id"), run_id) == run_id
    assert page.wait_for(VALUES_OF.format("/report_test/check"), rows) == rows
    srv.client.post(f"/api/runs/{run_id}/cancel")


LAYOUT = """(() => {
  const r = id => document.getElementById(id).getBoundingClientRect().toJSON();
  const doc = document.documentElement;
  const tree = document.getElementById("tree-scroll");
  const over = sel => Array.from(document.querySelectorAll(sel))
      .filter(e => e.scrollWidth > e.clientWidth + 1).map(e => e.className || e.tagName);
  return {width: innerWidth, height: innerHeight, scrollWidth: doc.scrollWidth,
          approvals: r("approvals-box"), approve: r("approvals").toJSON ? r("approvals") : null,
          button: document.querySelector('[data-action="approve"]')?.getBoundingClientRect().toJSON(),
          tree: r("tree-box"), treeContent: tree.scrollHeight, treeBox: tree.clientHeight,
          treeOverflowX: tree.scrollWidth - tree.clientWidth,
          boxes: Array.from(document.querySelectorAll(".box")).map(b => b.getBoundingClientRect().right),
          clipped: over("ul.log li, ul.log li .t, .box, header.top, li.node .status, .state")};
})()"""


@pytest.mark.parametrize("width", [800, 1400])
def test_layout_keeps_approvals_in_view_without_horizontal_scroll(monitor, chromium, tmp_path, width):
    srv = monitor(granted=1)
    run_id = srv.submit("big_test")
    page = chromium(srv.url + "/", width=width, height=900)
    assert page.wait_for(TEXT.format("run-id"), run_id) == run_id
    assert page.wait_for(node_status("/big_test/turn_the_knob"), "RUNNING") == "RUNNING"
    assert page.wait_for('document.querySelector(\'[data-action="approve"]\') !== null', True)
    # fill the logs past ten lines
    page.js('document.getElementById("show-writes").click()')
    got = page.js(LAYOUT)
    page.screenshot(tmp_path / f"monitor-{width}.png")
    assert got["width"] == width
    assert got["scrollWidth"] <= width, "the page scrolls sideways"
    assert max(got["boxes"]) <= width
    # The tree is taller than the window and scrolls in its own box...
    assert got["treeContent"] > 3000 and got["treeBox"] < 900
    assert got["treeOverflowX"] <= 1
    # ...so the approval and its button are in view without scrolling.
    assert got["approvals"]["top"] >= 0 and got["approvals"]["bottom"] <= got["height"]
    assert got["button"]["bottom"] <= got["height"]
    assert got["clipped"] == []
    assert page.js('document.querySelectorAll("#feedback li").length') > 10
    if width >= 1280:    # side by side at the window's height: the page itself does not scroll
        assert page.js("document.documentElement.scrollHeight") <= 900
        assert got["tree"]["bottom"] <= 900
    srv.client.post(f"/api/runs/{run_id}/cancel")


def test_api_docs_load_from_this_server_with_no_network(server, chromium):
    # Chromium here has no route out: Swagger UI comes from the server itself or not at all.
    page = chromium()
    page.call("Page.navigate", url=server.url + "/docs")
    assert page.wait_for('document.querySelectorAll(".opblock").length > 10', True)
    assert page.js('document.querySelector(".info .title")?.textContent').startswith("Hearth command API")


def test_the_page_shows_the_running_run_and_autonomy_before_the_mission_catalogue(make_server,
                                                                                  chromium):
    """The mission catalogue compiles every mission and may take seconds; the page must not
    say "no run yet" or autonomy 0 meanwhile while a mission runs."""
    import threading
    srv = make_server(granted=2)
    run_id = srv.client.post("/api/runs", json={"mission": "wait_test"}).json()["run"]["id"]
    release = threading.Event()
    catalogue = srv.service.missions

    def slow_catalogue():
        release.wait(60)                       # held until the page has been checked
        return catalogue()
    srv.service.missions = slow_catalogue
    try:
        page = chromium(srv.url + "/")
        assert page.wait_for(TEXT.format("run-mission"), "wait_test") == "wait_test"
        assert page.js('document.getElementById("autonomy").value') == "2"
        assert page.js('document.getElementById("autonomy").disabled') is False
        assert not release.is_set()            # the catalogue has not answered yet
    finally:
        release.set()
    srv.client.post(f"/api/runs/{run_id}/cancel", json={})
