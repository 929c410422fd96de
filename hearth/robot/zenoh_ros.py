"""ROS 2 over Zenoh without ROS: rmw_zenoh's key expressions, attachments and liveliness tokens,
CDR through ``rosbags``' serialisers (docs/ros2-foxglove.md, "A live robot").

What a ROS 2 node on ``rmw_zenoh_cpp`` (Jazzy and later) puts on the wire, as its design
document describes it (github.com/ros2/rmw_zenoh, docs/design.md, sections "Topic and Service
name mapping to Zenoh key expressions", "Graph Cache", "Publishers", "Service Clients",
"Service Servers"):

- a topic or service is the key ``<domain_id>/<fully qualified name without its leading
  slash>/<DDS type name>/<type hash>``, e.g.
  ``0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c74...``;
- the type hash is REP-2016's ``RIHS01_`` (sha256 of the type description; ``rosbags``
  computes it, see :func:`type_hash` for the one correction);
- a message is a Zenoh ``put`` of its CDR bytes with an attachment: sequence number (int64
  LE), source timestamp (int64 LE, ns since the UNIX epoch), the GID's length (one byte, 16)
  and the GID (16 bytes); a service request is a ``get`` with the same attachment and target
  ``ALL_COMPLETE``, served by a complete queryable, and the reply carries the request's
  sequence number and client GID back;
- every node and endpoint declares a liveliness token
  ``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/<enclave>/<namespace>/<node>
  [/<topic>/<type>/<hash>/<qos>]`` (names mangled: ``/`` -> ``%``), which vanishes when the
  entity or its session goes: that is how a lost link is seen.

ROS 2 actions are not an RMW concept: an action ``/a`` is the services
``/a/_action/send_goal``, ``/a/_action/cancel_goal``, ``/a/_action/get_result`` and the topics
``/a/_action/feedback`` and ``/a/_action/status`` (ROS 2 design, "Actions"), so they map onto
the above with the types ``<pkg>/action/<Name>_SendGoal`` etc.

Both sides of Hearth's live link use this module: ``hearth.robot.ros2_live`` (the adapter) and
``hearth.robot.zenoh_sim`` (a simulated robot serving the same names). Written by hand because
no Python library speaks rmw_zenoh's conventions without a ROS installation (the ``zenoh``
client moves bytes; ``rosbags`` encodes them).
"""
from __future__ import annotations

import itertools
import json
import os
import struct
import threading
import time
import uuid
from typing import Any, Callable, Optional

from hearth.robot.errors import RobotError

INSTALL = "pip install 'hearth[ros]' (eclipse-zenoh, rosbags)"
#: rmw_zenoh's default router endpoint (its DEFAULT_RMW_ZENOH_SESSION_CONFIG.json5 connects here).
DEFAULT_ENDPOINT = "tcp/localhost:7447"
ADMIN_SPACE = "@ros2_lv"
#: rmw_zenoh's compact QoS of a default (reliable, volatile, keep last 10) endpoint, as in its
#: design document's examples.
DEFAULT_QOS = "::,10:,:,:,,"
#: ... and of a latched (TRANSIENT_LOCAL, keep last 1) one, as /tf_static is declared in
#: ZettaScale's rmw_zenoh examples.
LATCHED_QOS = ":1:,1:,:,:,,"

NAV2_ACTION = ("nav2_msgs/action/NavigateToPose", """\
#goal definition
geometry_msgs/PoseStamped pose
string behavior_tree
""", """\
#result definition
std_msgs/Empty result
uint16 error_code
string error_msg
""", """\
#feedback definition
geometry_msgs/PoseStamped current_pose
builtin_interfaces/Duration navigation_time
builtin_interfaces/Duration estimated_time_remaining
int16 number_of_recoveries
float32 distance_remaining
""")

#: The arm, the charger and anything else that has no standard ROS 2 interface: one action a
#: robot serves (or bridges to MoveIt and its own controllers): ``task`` names what (one of
#: ``TASKS``), ``target`` the map id (part, knob, object, large object), ``handle`` a handle id,
#: ``value`` a joint state (rad or m) or knob angle (rad), ``pose`` a world pose in ``map``.
TASK_ACTION = ("hearth_msgs/action/RobotTask", """\
string task
string target
string handle
float64 value
geometry_msgs/PoseStamped pose
string args_json
""", """\
bool success
string message
string result_json
""", """\
float32 progress
string state
""")
TASKS = ("open_articulated", "close_articulated", "turn_knob", "grasp", "place", "hand_over",
         "dock", "undock")

_UUID = "unique_identifier_msgs/msg/UUID"
CANCEL_SRV = ("action_msgs/srv/CancelGoal", "action_msgs/msg/GoalInfo goal_info\n", """\
int8 ERROR_NONE=0
int8 ERROR_REJECTED=1
int8 ERROR_UNKNOWN_GOAL_ID=2
int8 ERROR_GOAL_TERMINATED=3
int8 return_code
action_msgs/msg/GoalInfo[] goals_canceling
""")
#: action_msgs/msg/GoalStatus
UNKNOWN, ACCEPTED, EXECUTING, CANCELING, SUCCEEDED, CANCELED, ABORTED = range(7)
TERMINAL = (SUCCEEDED, CANCELED, ABORTED)


def require_zenoh() -> None:
    try:
        import zenoh  # noqa: F401
        import rosbags.typesys  # noqa: F401
    except ImportError:
        raise RobotError(f"a live ROS 2 robot over Zenoh needs the ros extra: {INSTALL}") from None


# -- types ---------------------------------------------------------------------------------

def _rename(obj, old: str, new: str):
    """rosbags' .msg parser files every type under ``pkg/msg/``: services' and actions' parts
    live under ``pkg/srv/`` and ``pkg/action/``, which the type hash covers."""
    if isinstance(obj, str):
        return obj.replace(old, new) if "/" in obj else obj
    if isinstance(obj, (tuple, list)):
        return type(obj)(_rename(o, old, new) for o in obj)
    return obj


def _msgs(kind: str, name: str, texts: dict[str, str]) -> dict:
    from rosbags.typesys import get_types_from_msg
    pkg, _, base = name.split("/")
    out = {}
    for suffix, text in texts.items():
        out.update(get_types_from_msg(text, f"{pkg}/{kind}/{base}{suffix}"))
    old, new = f"{pkg}/{kind}/msg/", f"{pkg}/{kind}/"
    return {_rename(k, old, new): _rename(v, old, new) for k, v in out.items()}


def _service_texts(name: str, request: str, response: str) -> dict[str, str]:
    """A service's request, response, event and the service itself (rosidl's type description
    of a service: request_message, response_message, event_message)."""
    return {"_Request": request, "_Response": response,
            "_Event": (f"service_msgs/msg/ServiceEventInfo info\n{name}_Request[<=1] request\n"
                       f"{name}_Response[<=1] response\n"),
            "": (f"{name}_Request request_message\n{name}_Response response_message\n"
                 f"{name}_Event event_message\n")}


def _action_types(name: str, goal: str, result: str, feedback: str) -> dict:
    pkg, _, base = name.split("/")
    types = _msgs("action", name, {"_Goal": goal, "_Result": result, "_Feedback": feedback,
                                   "_FeedbackMessage": (f"{_UUID} goal_id\n"
                                                        f"{name}_Feedback feedback\n")})
    types.update(_msgs("action", name + "_SendGoal", _service_texts(
        name + "_SendGoal", f"{_UUID} goal_id\n{name}_Goal goal\n",
        "bool accepted\nbuiltin_interfaces/msg/Time stamp\n")))
    types.update(_msgs("action", name + "_GetResult", _service_texts(
        name + "_GetResult", f"{_UUID} goal_id\n", f"int8 status\n{name}_Result result\n")))
    return types


_STORE = None
_HASHES: dict[str, str] = {}
_LOCK = threading.Lock()


def typestore():
    """ROS 2 Jazzy's message types (rmw_zenoh runs on Jazzy and later) plus NavigateToPose,
    action_msgs' CancelGoal, Hearth's RobotTask action and Hearth's bag messages."""
    global _STORE
    with _LOCK:
        if _STORE is None:
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore

            from hearth.robot.rosbag import HEARTH_MSGS
            store = get_typestore(Stores.ROS2_JAZZY)
            types = {}
            for name, text in HEARTH_MSGS.items():
                types.update(get_types_from_msg(text, name))
            name, req, resp = CANCEL_SRV
            types.update(_msgs("srv", name, _service_texts(name, req, resp)))
            types.update(_action_types(*NAV2_ACTION))
            types.update(_action_types(*TASK_ACTION))
            store.register(types)
            _STORE = store
        return _STORE


def type_hash(typename: str) -> str:
    """REP-2016's RIHS01 hash of a message or service type (``pkg/msg/Name``,
    ``pkg/srv/Name``, ``pkg/action/Name_SendGoal``).

    rosbags' ``hash_rihs01`` gives ``char`` its own type id, but rosidl reads a .msg ``char``
    as ``uint8`` (rosidl_adapter's MSG_TYPE_TO_IDL), so the hash of anything holding
    ``service_msgs/ServiceEventInfo`` (every service) would differ from ROS's: it is taken on
    a copy of the type store with ``char`` read as ``uint8``. Checked against the hashes in
    rmw_zenoh's design document (std_msgs/String, example_interfaces/AddTwoInts) in
    tests/robot/test_ros2_live.py."""
    with _LOCK:
        h = _HASHES.get(typename)
    if h is not None:
        return h
    from rosbags.typesys.store import Typestore
    store = typestore()

    def uint8(o):
        if o == "char":
            return "uint8"
        if isinstance(o, (tuple, list)):
            return type(o)(uint8(x) for x in o)
        return o
    hasher = Typestore.__new__(Typestore)
    hasher.__dict__.update(store.__dict__)
    hasher.fielddefs = {k: (c, uint8(f)) for k, (c, f) in store.fielddefs.items()}
    h = hasher.hash_rihs01(typename)
    with _LOCK:
        _HASHES[typename] = h
    return h


def dds_type(typename: str) -> str:
    """``sensor_msgs/msg/Image`` -> ``sensor_msgs::msg::dds_::Image_`` (the type name as DDS
    declares it, which rmw_zenoh puts in its keys)."""
    pkg, kind, name = typename.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def mangle(name: str) -> str:
    return name.replace("/", "%") if name else "%"


def topic_key(domain: int, name: str, typename: str) -> str:
    """rmw_zenoh's key expression of a topic or service."""
    fq = name if name.startswith("/") else "/" + name
    return f"{int(domain)}/{fq.strip('/')}/{dds_type(typename)}/{type_hash(typename)}"


def attachment(seq: int, gid: bytes, stamp_ns: Optional[int] = None) -> bytes:
    """rmw_zenoh's attachment: sequence number, source timestamp (ns since the UNIX epoch,
    both int64 little-endian), the GID's length and the GID (16 bytes)."""
    ns = time.time_ns() if stamp_ns is None else int(stamp_ns)
    return struct.pack("<qqB16s", int(seq), ns, 16, bytes(gid[:16]).ljust(16, b"\0"))


def parse_attachment(data: Optional[bytes]) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp ns, GID); ValueError when it is not one."""
    if data is None or len(data) < 17:
        raise ValueError("no rmw_zenoh attachment")
    seq, ns, n = struct.unpack_from("<qqB", data)
    return seq, ns, bytes(data[17:17 + n])


def session_config(endpoint: str = DEFAULT_ENDPOINT, mode: str = "peer", listen: bool = True):
    """A Zenoh session configured as rmw_zenoh's default session (peer, connecting to the
    router, listening on loopback, no multicast scouting), or as its router (``mode="router"``,
    listening on ``endpoint``)."""
    import zenoh
    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("scouting/multicast/enabled", "false")
    # rmw_zenoh's session config timestamps samples (its latched publishers need it).
    c.insert_json5("timestamping/enabled", "true")
    if mode == "router":
        c.insert_json5("listen/endpoints", json.dumps([endpoint]))
    else:
        c.insert_json5("connect/endpoints", json.dumps([endpoint]))
        if listen:
            c.insert_json5("listen/endpoints", json.dumps(["tcp/127.0.0.1:0"]))
    return c


def open_session(endpoint: str = DEFAULT_ENDPOINT, mode: str = "peer"):
    require_zenoh()
    import re

    import zenoh
    if not re.fullmatch(r"[a-z][a-z0-9-]*/[^\s/]\S*", str(endpoint)):
        raise RobotError(f"{endpoint!r} is not a Zenoh endpoint (<protocol>/<address>, e.g. "
                         f"{DEFAULT_ENDPOINT})")
    try:
        return zenoh.open(session_config(endpoint, mode))
    except zenoh.ZError as err:
        raise RobotError(f"zenoh: cannot open a session on {endpoint}: {_plain(err)}") from None


def _plain(err) -> str:
    """Zenoh's error text without the Rust source locations it carries."""
    import re
    text = re.sub(r"\s+at \S+\.rs:\d+\.?", "", str(err))
    return re.sub(r"[\[\]]", "", text).strip().rstrip(".")


def stamp(ns: int, t=None):
    t = t or typestore().types
    ns = max(int(ns), 0)
    return t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def stamp_ns(msg_stamp) -> int:
    return int(msg_stamp.sec) * 1_000_000_000 + int(msg_stamp.nanosec)


def goal_id(data: bytes):
    return typestore().types[_UUID](uuid=__import__("numpy").frombuffer(bytes(data), "u1").copy())


class Node:
    """A ROS 2 node on one Zenoh session, as rmw_zenoh_cpp makes it: liveliness tokens for the
    node and each endpoint, rmw_zenoh's keys and attachments, CDR payloads.

    ``publisher(topic, type)`` -> ``publish(msg)``; ``subscribe(topic, type, callback)``
    (``callback(msg, source_stamp_ns)``); ``service(name, type, handler)`` where ``handler(
    request, reply)`` calls ``reply(response)`` now or later; ``call(name, type, request,
    callback, timeout)``. Thread-safe; callbacks run on Zenoh's threads."""

    def __init__(self, session, name: str, namespace: str = "", domain: Optional[int] = None):
        require_zenoh()
        self.session, self.name, self.namespace = session, name, namespace
        self.domain = int(os.environ.get("ROS_DOMAIN_ID") or 0) if domain is None else int(domain)
        self.store = typestore()
        self.types = self.store.types
        self.gid = uuid.uuid4().bytes
        self._ids = itertools.count(10)
        self._seq = itertools.count(1)
        self._lock = threading.Lock()
        self._keep: list = []
        self.zid = str(session.info.zid())
        self._token(f"{ADMIN_SPACE}/{self.domain}/{self.zid}/0/0/NN/%/{mangle(namespace)}/{name}")

    def _token(self, key: str):
        tok = self.session.liveliness().declare_token(key)
        self._keep.append(tok)
        return tok

    def _entity(self, kind: str, topic: str, typename: str, qos: str = DEFAULT_QOS) -> None:
        fq = topic if topic.startswith("/") else "/" + topic
        self._token(f"{ADMIN_SPACE}/{self.domain}/{self.zid}/0/{next(self._ids)}/{kind}/%/"
                    f"{mangle(self.namespace)}/{self.name}/{mangle(fq)}/{dds_type(typename)}/"
                    f"{type_hash(typename)}/{qos}")

    def key(self, topic: str, typename: str) -> str:
        return topic_key(self.domain, topic, typename)

    def encode(self, msg, typename: str) -> bytes:
        return bytes(self.store.serialize_cdr(msg, typename))

    def decode(self, data: bytes, typename: str):
        return self.store.deserialize_cdr(data, typename)

    def _attachment(self) -> bytes:
        with self._lock:
            seq = next(self._seq)
        return attachment(seq, self.gid)

    # -- topics
    def publisher(self, topic: str, typename: str, latched: bool = False) -> Callable[[Any], None]:
        """A function publishing ``typename`` messages on ``topic``. ``latched``: kept for
        subscribers that come later (TRANSIENT_LOCAL, as rmw_zenoh does it: an advanced
        publisher with a cache)."""
        self._entity("MP", topic, typename, LATCHED_QOS if latched else DEFAULT_QOS)
        if latched:
            import zenoh.ext as zx
            pub = zx.declare_advanced_publisher(self.session, self.key(topic, typename),
                                                cache=zx.CacheConfig(max_samples=1),
                                                publisher_detection=True)
        else:
            pub = self.session.declare_publisher(self.key(topic, typename))
        self._keep.append(pub)

        def publish(msg) -> None:
            pub.put(self.encode(msg, typename), attachment=self._attachment())
        return publish

    def subscribe(self, topic: str, typename: str, callback, latched: bool = False) -> None:
        """``callback(msg, source_stamp_ns)`` for every message; one that does not decode is
        dropped (a publisher of another definition has another key anyway)."""
        self._entity("MS", topic, typename, LATCHED_QOS if latched else DEFAULT_QOS)

        def on_sample(sample) -> None:
            try:
                msg = self.decode(sample.payload.to_bytes(), typename)
            except Exception:                          # noqa: BLE001 (rosbags raises several)
                return
            att = sample.attachment
            try:
                _, ns, _ = parse_attachment(att.to_bytes() if att is not None else None)
            except ValueError:
                ns = time.time_ns()
            callback(msg, ns)
        key = self.key(topic, typename)
        if latched:
            import zenoh.ext as zx
            sub = zx.declare_advanced_subscriber(
                self.session, key, on_sample,
                history=zx.HistoryConfig(detect_late_publishers=True, max_samples=1))
        else:
            sub = self.session.declare_subscriber(key, on_sample)
        self._keep.append(sub)

    # -- services
    def service(self, name: str, typename: str, handler) -> None:
        """Serve ``typename`` (``pkg/srv/Name`` or an action's ``..._SendGoal``) at ``name``:
        ``handler(request, reply)``; ``reply(response)`` may be called later from any thread
        (an action's get_result answers when the goal ends)."""
        self._entity("SS", name, typename)
        key = self.key(name, typename)

        def on_query(query) -> None:
            try:
                req = self.decode(query.payload.to_bytes(), typename + "_Request")
                seq, _, gid = parse_attachment(query.attachment.to_bytes()
                                               if query.attachment is not None else None)
            except Exception:                          # noqa: BLE001
                return

            def reply(resp) -> None:
                query.reply(query.key_expr, self.encode(resp, typename + "_Response"),
                            attachment=attachment(seq, gid))
                query.drop()
            handler(req, reply)
        self._keep.append(self.session.declare_queryable(key, on_query, complete=True))

    def client(self, name: str, typename: str) -> None:
        self._entity("SC", name, typename)

    def call(self, name: str, typename: str, request, callback=None, timeout: float = 5.0):
        """Send a request; ``callback(response or None)`` on Zenoh's thread, or (no callback)
        wait and return the response (None: no server answered within ``timeout`` s)."""
        import zenoh
        got: list = []
        done = threading.Event()

        def on_reply(reply) -> None:
            if reply.ok is not None and not got:
                try:
                    got.append(self.decode(reply.ok.payload.to_bytes(), typename + "_Response"))
                except Exception:                      # noqa: BLE001
                    pass

        def on_end() -> None:
            done.set()
            if callback is not None:
                callback(got[0] if got else None)
        self.session.get(self.key(name, typename), zenoh.handlers.Callback(on_reply, on_end),
                         payload=self.encode(request, typename + "_Request"),
                         attachment=self._attachment(), target=zenoh.QueryTarget.ALL_COMPLETE,
                         timeout=timeout)
        if callback is None:
            done.wait(timeout + 1.0)
            return got[0] if got else None
        return None

    def close(self) -> None:
        keep, self._keep = self._keep, []
        for k in reversed(keep):
            try:
                k.undeclare()
            except Exception:                          # noqa: BLE001 (already gone)
                pass


def action_names(action: str) -> dict[str, str]:
    a = action.rstrip("/")
    return {k: f"{a}/_action/{k}" for k in ("send_goal", "cancel_goal", "get_result",
                                            "feedback", "status")}
