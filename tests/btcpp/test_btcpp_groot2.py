"""A live mission over the Groot2 protocol, watched by third-party clients: btview's
Groot2Client, and a raw ZeroMQ client written from BehaviorTree.CPP's groot2_protocol.h."""
from __future__ import annotations

import json
import struct
from pathlib import Path

import pytest

zmq = pytest.importorskip("zmq")
btview_client = pytest.importorskip("btview.client")

from lxml import etree  # noqa: E402

from hearth.cli.main import main  # noqa: E402
from hearth.executive.executive import Executive  # noqa: E402
from hearth.executive.groot2 import Groot2Publisher  # noqa: E402
from hearth.executive.testing import Script, Substitution  # noqa: E402
from hearth import missions_dir  # noqa: E402
from hearth.robot.clock import SimClock  # noqa: E402

from .conftest import branching_case  # noqa: E402

MISSIONS = Path(missions_dir())
#: BT::NodeStatus as groot2_publisher.cpp records it.
CODE = {"RUNNING": 1, "SUCCESS": 2, "FAILURE": 3, "INVALID": 0}


class RawClient:
    """REQ socket speaking groot2_protocol.h: a 6-byte header (protocol 2, type, id)."""

    def __init__(self, port: int):
        self.ctx = zmq.Context()
        self.req = self.ctx.socket(zmq.REQ)
        self.req.setsockopt(zmq.RCVTIMEO, 5000)
        self.req.setsockopt(zmq.LINGER, 0)
        self.req.connect(f"tcp://127.0.0.1:{port}")
        self.rid = 0

    def ask(self, kind: str, payload: bytes | None = None) -> list[bytes]:
        self.rid += 1
        self.req.send_multipart([struct.pack("<BBI", 2, ord(kind), self.rid)]
                                + ([payload] if payload is not None else []))
        reply = self.req.recv_multipart()
        if reply[0] != b"error":
            protocol, rtype, rid = struct.unpack("<BBI", reply[0][:6])
            assert (protocol, chr(rtype), rid) == (2, kind, self.rid)
            assert len(reply[0]) == 22
        return reply

    def transitions(self) -> list[tuple[int, int, int]]:
        data = self.ask("t")[1]
        out = []
        for i in range(0, len(data), 9):
            usec = int.from_bytes(data[i:i + 6], "little")
            uid, status = struct.unpack("<HB", data[i + 6:i + 9])
            out.append((usec, uid, status))
        return out

    def close(self) -> None:
        self.ctx.destroy(linger=0)


def paths_by_uid(xml: str) -> dict[int, str]:
    """Hearth paths from what a Groot2 client gets: names, SubTree _fullpath, _uid."""
    root = etree.fromstring(xml.encode("utf-8"))
    trees = {t.get("_fullpath"): t for t in root.iter("BehaviorTree")}
    out: dict[int, str] = {}

    def walk(el, prefix: str) -> None:
        if el.tag == "State":            # a wrapper that mirrors its child (not a Hearth node)
            for c in el:
                walk(c, prefix)
            return
        if el.tag == "SubTree":
            path = "/" + el.get("_fullpath")
            out[int(el.get("_uid"))] = path
            walk(trees[el.get("_fullpath")][0], path)
            return
        path = f"{prefix}/{el.get('name')}"
        out[int(el.get("_uid"))] = path
        for c in el:
            walk(c, path)
    walk(trees[""][0], "")
    return out


def watch(mission: str, case, tmp_path, background: bool = True):
    """Run ``mission`` with a publisher and clients attached; return what they saw."""
    sub = Substitution(case.scripts, case.default)
    ex = Executive(clock=SimClock(), make_skill=sub, background=background,
                   runs_dir=str(tmp_path / "runs"))
    pub = Groot2Publisher(ex, port=0)
    raw = RawClient(pub.port)
    viewer = btview_client.Groot2Client(port=pub.port, timeout_ms=5000)
    try:
        assert raw.ask("r", b"start")[1].isdigit()
        handle = ex.submit(mission, **case.params)
        seen = []
        if background:
            while not handle.done:
                seen += raw.transitions()
                handle.wait(0.05)
        else:
            ex.run_until_idle(100_000)
        seen += raw.transitions()
        xml = raw.ask("T")[1].decode("utf-8")
        tree = viewer.fetch_tree()
        final = viewer.poll().statuses
        return handle, xml, tree, final, seen, raw, pub
    finally:
        viewer.close()
        raw.close()
        pub.close()
        ex.shutdown()


def logged(handle) -> list[tuple[str, int]]:
    return [(e["path"], CODE[e["status"]]) for e in map(json.loads, open(handle.log_path))
            if e["e"] == "status"]


@pytest.mark.parametrize("mission", ["fetch_object.yaml", "turn_off_oven.yaml"])
def test_a_groot2_client_sees_every_logged_status_change_in_order(tmp_path, mission):
    path = str(MISSIONS / mission)
    handle, xml, tree, final, seen, _, _ = watch(path, branching_case(path), tmp_path)
    uid_path = paths_by_uid(xml)
    mirrors = {u for u in (n.uid for n in tree.walk()) if u not in uid_path}
    received = [(uid_path[uid], status) for _, uid, status in seen if uid not in mirrors]
    assert len(received) > 20
    assert received == logged(handle)
    assert [t for t, _, _ in seen] == sorted(t for t, _, _ in seen)
    # btview parsed the same tree (every Hearth node, includes expanded) and its last
    # snapshot is how each node ended.
    assert {n.uid for n in tree.walk()} == set(uid_path)
    last = {}
    for p, status in logged(handle):
        last[p] = status
    by_path = {uid_path[u]: s for u, s in final.items()}
    for p, status in last.items():
        assert by_path[p].status.value == status or (
            status == 0 and by_path[p].status.name == "IDLE")


def test_a_watch_restart_shows_halted_nodes_going_idle(tmp_path):
    from hearth.executive.testing import load_mission_case
    case = load_mission_case(Path(__file__).parents[1] / "executive" / "cases" /
                     "go_to_rest_presence_change.yaml")
    sub = Substitution(case.scripts, case.default)
    ex = Executive(clock=SimClock(), make_skill=sub, background=False,
                   runs_dir=str(tmp_path / "runs"))
    with Groot2Publisher(ex, port=0) as pub:
        raw = RawClient(pub.port)
        raw.ask("r", b"start")
        handle = ex.submit(str(MISSIONS / "go_to_rest.yaml"), **case.params)
        start, changes, snapshots = ex.clock.now(), list(case.set_parameters), []
        for _ in range(200):
            while changes and changes[0][0] <= ex.clock.now() - start + 1e-9:
                for k, v in changes.pop(0)[1].items():
                    ex.set_parameter(k, v)
            if not ex.tick():
                break
            status = raw.ask("S")[1]
            snapshots.append(dict(struct.unpack("<HB", status[i:i + 3])
                                  for i in range(0, len(status), 3)))
        uid_path = paths_by_uid(raw.ask("T")[1].decode())
        received = [(uid_path[u], s) for _, u, s in raw.transitions()]
        raw.close()
    ex.shutdown()
    assert handle.result.outcome == "succeeded"
    assert received == logged(handle)
    drive = next(u for u, p in uid_path.items() if p.endswith("/drive_near_user"))
    # Halted while running: BT.CPP's "idle from running" (10 + RUNNING) in the snapshot.
    assert 11 in [snap[drive] for snap in snapshots]


def test_requests_hearth_does_not_serve_get_an_error_reply(tmp_path):
    ex = Executive(clock=SimClock(), make_skill=Substitution([], Script()), background=False,
                   runs_dir=None)
    with Groot2Publisher(ex, port=0) as pub:
        raw = RawClient(pub.port)
        assert raw.ask("T")[0] == b"error"                       # nothing has run yet
        assert raw.ask("I", b'{"uid": 1}') == [b"error", b"Hearth does not support breakpoints"]
        raw.req.send_multipart([b"xx"])
        assert raw.req.recv_multipart() == [b"error", b"wrong request header"]
        assert raw.ask("D")[1] == b"[]"
        ex.submit(str(MISSIONS / "go_to_rest.yaml"), presence="away")
        ex.run_until_idle(1000)
        import msgpack
        bb = msgpack.unpackb(raw.ask("B", b"go_to_rest")[1])
        assert bb["go_to_rest"]["$presence"] == "away"
        raw.close()
    ex.shutdown()


def test_cli_run_with_a_port_in_use_is_one_line_exit_2(tmp_path, capsys):
    ctx = zmq.Context()
    taken = ctx.socket(zmq.REP)
    port = taken.bind_to_random_port("tcp://127.0.0.1")
    try:
        assert main(["run", str(MISSIONS / "go_to_rest.yaml"), "--groot2", str(port),
                     "--runs-dir", str(tmp_path / "runs"), "--quiet"]) == 2
    finally:
        ctx.destroy(linger=0)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("groot2: cannot listen on 127.0.0.1:")


def test_serve_and_run_take_groot2_with_a_default_port():
    from hearth.cli.main import build_parser
    parser = build_parser()
    serve = parser.parse_args(["serve", "--groot2"])
    assert (serve.groot2, serve.groot2_host) == (1667, "127.0.0.1")
    run = parser.parse_args(["run", "m.yaml", "--groot2", "1800", "--groot2-host", "0.0.0.0"])
    assert (run.groot2, run.groot2_host) == (1800, "0.0.0.0")
    assert parser.parse_args(["run", "m.yaml"]).groot2 is None


def test_a_viewer_sees_the_mission_tree_before_its_run_starts_and_subtrees_by_name(tmp_path):
    from hearth.executive.missionfile import load_mission
    mission = load_mission(MISSIONS / "fetch_object.yaml")
    ex = Executive(clock=SimClock(), make_skill=Substitution([], Script()), background=False,
                   runs_dir=None)
    with Groot2Publisher(ex, port=0) as pub:
        pub.show(mission)                    # as `hearth run --groot2` does before submitting
        raw = RawClient(pub.port)
        reply = raw.ask("T")
        assert reply[0] != b"error"
        root = etree.fromstring(reply[1])
        assert root.get("main_tree_to_execute") == "fetch_object"
        calls = list(root.iter("SubTree"))
        assert calls and all(c.get("name") and c.get("name") != "SubTree" for c in calls)
        status = raw.ask("S")[1]
        assert set(status[i + 2] for i in range(0, len(status), 3)) == {0}   # all idle
        raw.close()
    ex.shutdown()
