"""A running mission over the Groot2 protocol, so Groot2, btview and other Groot2 clients
can watch it live.

The protocol is BehaviorTree.CPP's (``include/behaviortree_cpp/loggers/groot2_protocol.h`` and
``src/loggers/groot2_publisher.cpp``, protocol 2): ZeroMQ REQ/REP on ``port`` and a PUB socket
on ``port + 1`` (BT.CPP sends breakpoint notices there; Hearth has no breakpoints, so it
stays silent). Every request is multipart; its first frame is a 6-byte header (protocol
``uint8`` = 2, request type ``uint8``, request id ``uint32`` little-endian) and every reply
starts with the same 6 bytes and the 16-byte id of the tree. Written here from that header:
no Python package serves it.

Requests answered, as BT.CPP answers them:

* ``T`` full tree: the running mission as ``WriteTreeToXML(tree, add_metadata=true)`` writes
  it (:func:`hearth.executive.btcpp.live_tree`: every node with its ``_uid``, each include as a
  ``<SubTree>`` and its own ``<BehaviorTree _fullpath=...>``);
* ``S`` statuses: 3 bytes per node, ``uint16`` uid and the status (0 idle, 1 running,
  2 success, 3 failure; 10 + the previous one when a node went back to idle, as BT.CPP marks
  a halted or reset node);
* ``r`` start|stop recording, ``t`` the transitions recorded since the last ``t`` (9 bytes
  each: 6 bytes of microseconds since the start of the recording, uid, status), so a client
  sees every status change in order, not only the latest;
* ``B`` blackboards (``;``-separated subtree names; MessagePack of ``{name: {key: value}}``;
  the mission's own keys and its ``$parameters``; needs ``msgpack``);
* ``D`` hooks (always ``[]``), ``A`` and ``X`` (nothing to do). Breakpoint requests (``I``,
  ``R``, ``U``) get an error reply: Hearth does not stop a tick for a debugger.

The statuses come from the Executive's public event stream (``Executive.subscribe``): each
``status`` event of the current mission, the same events the JSON-lines log records, in the
same order. The tree is built from ``Executive.current_tree`` when a mission starts and kept
after it ends, so a viewer sees how it ended. Binds on 127.0.0.1 unless told otherwise.
"""
from __future__ import annotations

import json
import logging
import os
import struct
import threading
import time
from typing import Any

from hearth.executive.errors import MissionError

log = logging.getLogger(__name__)

PROTOCOL_ID = 2
DEFAULT_PORT = 1667
_HEADER = struct.Struct("<BBI")
_STATUS = {"RUNNING": 1, "SUCCESS": 2, "FAILURE": 3, "INVALID": 0}
_FINAL = ("succeeded", "failed", "cancelled", "preempted")
#: A bound on the recorded transitions a client has not fetched yet (BT.CPP keeps 1000).
MAX_TRANSITIONS = 100_000


class Groot2Error(MissionError):
    """The publisher could not start (a port in use, pyzmq missing)."""


class Groot2Publisher:
    """Publish ``executive``'s running mission over the Groot2 protocol.

    ``port`` 0 picks a free pair of ports (see :attr:`port`). Use as a context manager or
    call :meth:`close`."""

    def __init__(self, executive: Any, port: int = DEFAULT_PORT, host: str = "127.0.0.1"):
        try:
            import zmq
        except ImportError as err:
            raise Groot2Error(f"--groot2 needs pyzmq ({err}); pip install -e '.[btcpp]'") \
                from None
        self._zmq = zmq
        self.executive = executive
        self.host = host
        self._ctx = zmq.Context()
        self._rep, self._pub, self.port = self._bind(port)
        self._lock = threading.Lock()
        self._run: str | None = None
        self._pending: str | None = None
        self._built: Any = None
        self._live: Any = None
        self._final_bb: dict | None = None
        self._uuid = bytes(16)
        self._status: dict[int, int] = {}
        self._recording = False
        self._record_t0 = 0.0
        self._record_mono = 0.0
        self._transitions: list[tuple[int, int, int]] = []
        self.requests = 0
        self._closed = threading.Event()
        self._unsubscribe = executive.subscribe(self._on_event)
        self._thread = threading.Thread(target=self._serve, name="groot2", daemon=True)
        self._thread.start()

    # -- sockets ------------------------------------------------------------------------
    def _bind(self, port: int):
        zmq = self._zmq
        tries = 20 if port == 0 else 1
        last: Exception | None = None
        for _ in range(tries):
            rep = self._ctx.socket(zmq.REP)
            pub = self._ctx.socket(zmq.PUB)
            for s in (rep, pub):
                s.setsockopt(zmq.LINGER, 0)
                s.setsockopt(zmq.SNDTIMEO, 1000)
            try:
                if port == 0:
                    p = rep.bind_to_random_port(f"tcp://{self.host}", 20000, 60000)
                else:
                    rep.bind(f"tcp://{self.host}:{port}")
                    p = port
                pub.bind(f"tcp://{self.host}:{p + 1}")
                return rep, pub, p
            except zmq.ZMQError as err:
                last = err
                rep.close(0)
                pub.close(0)
        self._ctx.term()
        raise Groot2Error(f"groot2: cannot listen on {self.host}:{port} and the next port: "
                          f"{last}")

    def show(self, mission: Any) -> None:
        """Serve ``mission``'s tree (every node idle) until a run of the executive starts:
        a viewer that attaches while the run is still being set up sees the tree at once,
        not "no mission has run yet"."""
        from hearth.executive.btcpp import live_tree
        live = live_tree(mission)
        with self._lock:
            if self._run is not None:
                return
            self._live = live
            self._mission_name = mission.name
            self._uuid = os.urandom(16)
            self._status = {u: 0 for u in live.order}

    def close(self) -> None:
        """Stop serving and unsubscribe (idempotent)."""
        if self._closed.is_set():
            return
        self._unsubscribe()
        self._closed.set()
        self._thread.join(timeout=5)
        self._ctx.term()

    def __enter__(self) -> "Groot2Publisher":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # -- the executive's events (tick thread) -------------------------------------------
    def _on_event(self, ev: Any) -> None:
        if ev.run != self._run:
            if not self._adopt(ev.run):
                return
        if ev.kind == "run" and ev.data.get("state") in _FINAL:
            # The run's keys are removed when it ends: keep what a viewer would last see.
            snapshot = self._main_blackboard() if self._built is not None else {}
            handle = self.executive.handle_of(ev.run) if hasattr(self.executive, "handle_of") else None
            if handle is not None and not snapshot:
                # Delivered after the run ended: what it kept are its outputs and parameters.
                result = handle.result
                snapshot = dict(result.outputs if result is not None else {})
                snapshot.update({f"${k}": v for k, v in handle.params.items()})
                snapshot = json.loads(json.dumps(snapshot, default=repr))
            with self._lock:
                self._final_bb = snapshot
            return
        if ev.kind != "status" or ev.path is None:
            return
        live = self._live
        uid = live.uid.get(ev.path)
        if uid is None:
            return
        st = ev.data.get("status")
        code = _STATUS.get(st, 0)
        shown = code
        if st == "INVALID":
            prev = _STATUS.get(ev.data.get("previous"), 0)
            shown = 10 + prev if prev else 0
        with self._lock:
            for u in (uid, *live.mirrors.get(ev.path, ())):
                self._status[u] = shown
                if self._recording and len(self._transitions) < MAX_TRANSITIONS:
                    usec = int((time.monotonic() - self._record_mono) * 1e6)
                    self._transitions.append((usec, u, code))

    def _adopt(self, run: str) -> bool:
        """Start showing ``run`` once the Executive has its tree (from its first tick on)."""
        from hearth.executive.btcpp import live_tree
        # Events reach subscribers from the executive's delivery thread, after the fact: the
        # run may have ended by now, so take its mission from its handle, and its tree (for
        # the blackboard) only while it is still the current one.
        handle = self.executive.handle_of(run) if hasattr(self.executive, "handle_of") else None
        current = self.executive.current
        built = self.executive.current_tree if current is not None and current.id == run else None
        if handle is None:
            return False
        live = live_tree(handle.mission)
        with self._lock:
            self._run, self._built, self._live = run, built, live
            self._mission_name = handle.mission.name
            self._final_bb = None
            self._uuid = os.urandom(16)
            self._status = {u: 0 for u in live.order}
        return True

    # -- requests (server thread) -------------------------------------------------------
    def _serve(self) -> None:
        zmq = self._zmq
        poller = zmq.Poller()
        poller.register(self._rep, zmq.POLLIN)
        try:
            while not self._closed.is_set():
                if not poller.poll(100):
                    continue
                frames = self._rep.recv_multipart()
                self.requests += 1
                try:
                    reply = self._answer(frames)
                except Exception as err:  # noqa: BLE001 - a bad request must not kill us
                    log.exception("groot2 request failed")
                    reply = [b"error", str(err).encode()]
                self._rep.send_multipart(reply)
        except zmq.ZMQError as err:
            if not self._closed.is_set():
                log.warning("groot2 server stopped: %s", err)
        finally:
            self._rep.close(0)
            self._pub.close(0)

    def _answer(self, frames: list[bytes]) -> list[bytes]:
        if not frames or len(frames[0]) != _HEADER.size:
            return [b"error", b"wrong request header"]
        _, rtype, rid = _HEADER.unpack(frames[0])
        kind = chr(rtype)
        with self._lock:
            head = _HEADER.pack(PROTOCOL_ID, rtype, rid) + self._uuid
            live = self._live
            if kind in "TSBt" and live is None and kind != "t":
                return [b"error", b"no mission has run yet"]
            if kind == "T":
                return [head, live.xml.encode("utf-8")]
            if kind == "S":
                buf = bytearray()
                for u in live.order:
                    buf += struct.pack("<HB", u, self._status.get(u, 0))
                return [head, bytes(buf)]
            if kind == "r":
                if len(frames) != 2:
                    return [b"error", b"must be 2 parts message"]
                cmd = frames[1].decode("utf-8", "replace")
                if cmd == "start":
                    self._record_t0 = time.time()
                    self._record_mono = time.monotonic()
                    self._transitions = []
                    self._recording = True
                    return [head, str(int(self._record_t0 * 1e6)).encode()]
                if cmd == "stop":
                    self._recording = False
                return [head]
            if kind == "t":
                out = bytearray()
                for usec, u, code in self._transitions:
                    out += struct.pack("<Q", usec)[:6] + struct.pack("<HB", u, code)
                self._transitions = []
                return [head, bytes(out)]
            if kind == "B":
                if len(frames) != 2:
                    return [b"error", b"must be 2 parts message"]
                return self._blackboard(head, frames[1].decode("utf-8", "replace"))
            if kind == "D":
                return [head, b"[]"]
            if kind in "AX":
                return [head]
            if kind in "IRU":
                return [b"error", b"Hearth does not support breakpoints"]
        return [b"error", b"Request not recognized"]

    def _main_blackboard(self) -> dict[str, Any]:
        """The mission's own keys and its $parameters, as JSON values."""
        if self._built is None:
            return {}
        values = {k: v for k, v in self._built.blackboard().items() if "/" not in k}
        return json.loads(json.dumps(values, default=repr))

    def _blackboard(self, head: bytes, names: str) -> list[bytes]:
        try:
            import msgpack
        except ImportError:
            return [b"error", b"blackboard dumps need msgpack (pip install -e '.[btcpp]')"]
        out: dict[str, Any] = {}
        main = getattr(self, "_mission_name", None)
        for name in filter(None, names.split(";")):
            if name == main:
                out[name] = self._final_bb if self._final_bb is not None \
                    else self._main_blackboard()
            elif name in self._live.instances:
                out[name] = {}   # keys private to an include are not mapped back (yet)
        return [head, msgpack.packb(out, use_bin_type=True)]
