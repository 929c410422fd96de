"""A live ROS 2 robot over Zenoh (hearth/robot/ros2_live.py, docs/ros2-foxglove.md "A live
robot"): Hearth's simulated robot served with rmw_zenoh's conventions on a real Zenoh session
(zenoh's own peer, in this process, on a port and ROS domain of its own), missions run through
the Ros2Robot adapter, cancel and a lost link; names checked against rmw_zenoh's design
document, messages against a fresh rosbags type store."""
from __future__ import annotations

import json
import random
import socket
import time

import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh", reason="the ros extra (eclipse-zenoh) is not installed")
pytest.importorskip("rosbags", reason="the ros extra (rosbags) is not installed")

from hearth.robot.clock import WallClock  # noqa: E402
from hearth.robot.zenoh_ros import (ADMIN_SPACE, CANCELED, EXECUTING, NAV2_ACTION,  # noqa: E402
                                    SUCCEEDED, attachment, parse_attachment, session_config,
                                    topic_key, type_hash)

# rmw_zenoh docs/design.md, "Topic and Service name mapping to Zenoh key expressions"
DESIGN_STRING_KEY = ("0/chatter/std_msgs::msg::dds_::String_/"
                     "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18")
DESIGN_SERVICE_KEY = ("2/add_two_ints/example_interfaces::srv::dds_::AddTwoInts_/"
                      "RIHS01_e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a")
RATE = 4.0              # the simulated robot runs four times real time


def _free_endpoint() -> str:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return f"tcp/127.0.0.1:{port}"


def _listening_session(endpoint: str):
    """A Zenoh peer listening on ``endpoint`` (the robot's side; the adapter connects)."""
    c = session_config(endpoint, mode="peer", listen=False)
    c.insert_json5("connect/endpoints", "[]")
    c.insert_json5("listen/endpoints", json.dumps([endpoint]))
    return zenoh.open(c)


@pytest.fixture(scope="module")
def live():
    """turn_off_oven's seed-0 case (knobs on, localisation off) served as a ROS 2 robot, and
    a Ros2Robot connected to it over TCP."""
    from hearth.executive.scenarios import Case, make_case_scenario
    from hearth.robot.ros2_live import Ros2Robot
    from hearth.robot.simulated import SimulatedRobot
    from hearth.robot.zenoh_sim import ScaledClock, SimRobotServer

    sc, params, target = make_case_scenario(Case("turn_off_oven", seed=0))
    endpoint = _free_endpoint()
    domain = random.randint(100, 230)          # rmw_zenoh's key prefix: this test's own
    session = _listening_session(endpoint)
    sim = SimulatedRobot(sc.truth, clock=ScaledClock(RATE), start_pose=sc.start_pose,
                         localisation_error=sc.localisation_error, seed=0)
    server = SimRobotServer(sim, session, camera_rate=4.0, domain=domain)
    robot = Ros2Robot(world=sc.belief, endpoint=endpoint, domain=domain, connect_timeout=20)
    live = dict(sc=sc, params=params, target=target, sim=sim, server=server, robot=robot,
                endpoint=endpoint, domain=domain, session=session)

    def restart():
        """The robot comes back (a new node on the same robot)."""
        live["server"].close()
        live["server"] = SimRobotServer(sim, session, camera_rate=4.0, domain=domain)
    live["restart"] = restart
    yield live
    robot.close()
    live["server"].close()
    session.close()


def _executive(live):
    from hearth.executive.executive import Executive
    return Executive(world=live["sc"].belief, robot=live["robot"], clock=WallClock(),
                     tick_hz=20.0, background=False)


# -- names and encodings ---------------------------------------------------------------------

def test_keys_and_hashes_are_the_ones_rmw_zenoh_documents():
    from hearth.robot.zenoh_ros import _msgs, _service_texts, typestore
    assert topic_key(0, "/chatter", "std_msgs/msg/String") == DESIGN_STRING_KEY
    assert type_hash("std_msgs/msg/String") == DESIGN_STRING_KEY.rsplit("/", 1)[1]
    # a service's hash covers its request, response and event (how the actions' send_goal,
    # get_result and cancel_goal are hashed): the design document's add_two_ints
    name = "example_interfaces/srv/AddTwoInts"
    typestore().register(_msgs("srv", name, _service_texts(name, "int64 a\nint64 b\n",
                                                           "int64 sum\n")))
    assert topic_key(2, "/add_two_ints", name) == DESIGN_SERVICE_KEY
    # as ZettaScale's rmw_zenoh subscriber example declares them
    assert type_hash("tf2_msgs/msg/TFMessage") == \
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"
    assert type_hash("sensor_msgs/msg/PointCloud2") == \
        "RIHS01_9198cabf7da3796ae6fe19c4cb3bdd3525492988c70522628af5daa124bae2b5"
    seq, ns, gid = parse_attachment(attachment(7, b"g" * 16, stamp_ns=123))
    assert (seq, ns, gid) == (7, 123, b"g" * 16)
    assert len(attachment(7, b"g" * 16)) == 33          # int64 seq, int64 stamp, len, 16-byte gid


def test_the_robot_declares_rmw_zenoh_liveliness_tokens(live):
    d = live["domain"]
    keys = [str(r.ok.key_expr) for r in live["session"].liveliness().get(
        f"{ADMIN_SPACE}/{d}/**", timeout=2.0) if r.ok is not None]
    node = [k for k in keys if "/NN/" in k and k.endswith("/hearth_sim_robot")]
    assert len(node) == 1 and node[0].split("/")[6:] == ["%", "%", "hearth_sim_robot"]
    nav = [k.split("/") for k in keys if "/SS/" in k and "%navigate_to_pose%_action%send_goal" in k]
    assert nav and nav[0][10] == "nav2_msgs::action::dds_::NavigateToPose_SendGoal_"
    assert nav[0][11] == type_hash(NAV2_ACTION[0] + "_SendGoal")
    tf = [k.split("/") for k in keys if "/MP/" in k and "/%tf/" in k]
    assert tf and tf[0][10:12] == ["tf2_msgs::msg::dds_::TFMessage_",
                                   type_hash("tf2_msgs/msg/TFMessage")]


def test_what_the_robot_publishes_decodes_with_a_fresh_rosbags_store(live):
    """Colour, depth, camera_info and tf as they come off the wire, read by rosbags' own ROS 2
    Jazzy types (not the store Hearth encodes with)."""
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    d, m = live["domain"], live["server"].topic
    want = {"color": (m["color"], "sensor_msgs/msg/Image"),
            "depth": (m["depth"], "sensor_msgs/msg/Image"),
            "info": (m["camera_info"], "sensor_msgs/msg/CameraInfo"),
            "tf": ("/tf", "tf2_msgs/msg/TFMessage")}
    got: dict = {}
    subs = [live["session"].declare_subscriber(
        topic_key(d, topic, typ),
        lambda s, role=role, typ=typ: got.setdefault(role, (s.payload.to_bytes(), typ)))
        for role, (topic, typ) in want.items()]
    t_end = time.monotonic() + 5
    while len(got) < len(want) and time.monotonic() < t_end:
        time.sleep(0.05)
    for s in subs:
        s.undeclare()
    assert set(got) == set(want)
    msgs = {role: store.deserialize_cdr(data, typ) for role, (data, typ) in got.items()}
    c, z, info = msgs["color"], msgs["depth"], msgs["info"]
    assert (c.encoding, z.encoding) == ("rgb8", "16UC1")
    assert c.header.frame_id == z.header.frame_id == info.header.frame_id
    assert len(c.data) == c.height * c.step and c.step == 3 * c.width
    assert np.frombuffer(z.data.tobytes(), "<u2").max() > 500      # millimetres, registered
    assert info.k[0] > 0 and info.width == c.width
    frames = {(t.header.frame_id, t.child_frame_id) for t in msgs["tf"].transforms}
    assert ("odom", "base_link") in frames


def test_one_clock_and_one_tree_map_odom_base_camera_at_10_hz(live):
    """The robot's stamps are its own clock (simulated: from the fixed epoch 1700000000 s);
    tf while it stands runs at >= 10 Hz of robot time; a frame's camera pose is map -> odom ->
    base_link -> camera at the image's stamp."""
    from hearth.robot.zenoh_sim import SIM_EPOCH
    robot, server = live["robot"], live["server"]
    n0 = len(server.tf_stamps)
    time.sleep(1.0)
    stamps = np.array(server.tf_stamps[n0:], dtype=np.int64)
    span_s = (stamps[-1] - stamps[0]) * 1e-9
    assert (len(stamps) - 1) / span_s >= 10.0
    assert SIM_EPOCH <= robot.robot_time_ns() * 1e-9 < SIM_EPOCH + 3600
    f = robot.capture()
    assert SIM_EPOCH < f.timestamp <= robot.robot_time_ns() * 1e-9
    tf = robot._tf
    assert tf.connected("map", "odom") and tf.connected("odom", "base_link")
    assert tf.connected("base_link", server.camera_frame)
    T_bc = tf.lookup_at("base_link", server.camera_frame, int(f.timestamp * 1e9))
    np.testing.assert_allclose(f.base_pose.matrix() @ T_bc, f.T_world_camera, atol=1e-6)


# -- missions --------------------------------------------------------------------------------

def test_turn_off_oven_runs_through_the_live_adapter(live):
    sc, target, sim = live["sc"], live["target"], live["sim"]
    on = [k.id for k in sc.truth.knobs(target) if k.state != k.off]
    assert on                                   # the case has knobs on
    ex = _executive(live)
    handle = ex.submit("missions/turn_off_oven.yaml", **live["params"])
    ex.run_until_idle()
    r = handle.result
    assert r.outcome == "succeeded", r.reason
    assert all(k.state == k.off for k in sc.truth.knobs(target))     # truth: really off
    # the localisation fix went over the wire (initialpose): believed and true poses agree
    assert sim.base_pose().planar_distance(sim.true_pose()) < 0.02
    nav = [g for g in live["server"].nav.goals.values()]
    assert nav and all(g["status"] == SUCCEEDED for g in nav)


def test_cancelling_a_mission_cancels_the_navigation_goal(live):
    server, sim = live["server"], live["sim"]
    ex = _executive(live)
    before = set(server.nav.goals)
    belief = live["sc"].belief
    far = max(belief.large_objects(), key=lambda o: min(
        pose.planar_distance(sim.base_pose()) for _, pose in belief.parking_positions(o.id)))
    handle = ex.submit("missions/go_to_rest.yaml", rest_near_user=far.id)
    t_end = time.monotonic() + 10
    new: list = []
    while time.monotonic() < t_end:
        ex.tick()
        new = [g for k, g in server.nav.goals.items() if k not in before]
        if new and new[0]["status"] == EXECUTING:
            break
        time.sleep(0.02)
    assert new and new[0]["status"] == EXECUTING
    handle.cancel("the user said stop")
    ex.run_until_idle()
    assert handle.result.outcome == "cancelled"
    t_end = time.monotonic() + 3
    while new[0]["status"] != CANCELED and time.monotonic() < t_end:
        time.sleep(0.02)
    assert new[0]["status"] == CANCELED
    assert min(pose.planar_distance(sim.base_pose())                 # it stopped on the way
               for _, pose in belief.parking_positions(far.id)) > 0.1


def _farthest_object(live):
    belief, sim = live["sc"].belief, live["sim"]
    return max(belief.large_objects(), key=lambda o: min(
        pose.planar_distance(sim.base_pose()) for _, pose in belief.parking_positions(o.id)))


def test_hearth_run_ros2_drives_the_live_robot(live, tmp_path, monkeypatch, capsys):
    from hearth.cli.main import main
    monkeypatch.setenv("ROS_DOMAIN_ID", str(live["domain"]))
    far = _farthest_object(live)
    rc = main(["run", "go_to_rest", "--no-save", "--quiet", "--runs-dir", str(tmp_path),
               "--ros2", live["endpoint"], "--param", f"rest_near_user={far.id}"])
    out = capsys.readouterr()
    assert rc == 0, out
    assert out.out.startswith("go_to_rest: succeeded")
    sim, belief = live["sim"], live["sc"].belief
    assert min(pose.planar_distance(sim.base_pose())
               for _, pose in belief.parking_positions(far.id)) < 0.05


def test_a_link_lost_during_hearth_run_is_one_line_and_exit_2(live, tmp_path, monkeypatch,
                                                              capsys):
    import threading

    from hearth.cli.main import main
    monkeypatch.setenv("ROS_DOMAIN_ID", str(live["domain"]))
    server = live["server"]
    before = set(server.nav.goals)

    def pull_the_plug():
        t_end = time.monotonic() + 30
        while time.monotonic() < t_end:
            new = [g for k, g in server.nav.goals.items() if k not in before]
            if new and new[0]["status"] == EXECUTING:
                server.close()
                return
            time.sleep(0.02)
    th = threading.Thread(target=pull_the_plug, daemon=True)
    th.start()
    far = _farthest_object(live)
    rc = main(["run", "go_to_rest", "--no-save", "--quiet", "--runs-dir", str(tmp_path),
               "--ros2", live["endpoint"], "--param", f"rest_near_user={far.id}"])
    th.join(5)
    out = capsys.readouterr()
    err = out.err.strip().splitlines()
    assert rc == 2, out
    assert len(err) == 1 and err[0].startswith("lost the link to the robot: its "
                                               "NavigateToPose server /navigate_to_pose left")
    live["restart"]()
    robot = live["robot"]                       # the fixture's adapter: back when the robot is
    t_end = time.monotonic() + 5
    while robot.link_lost() and time.monotonic() < t_end:
        time.sleep(0.05)
    assert robot.link_lost() is None
    t_end = time.monotonic() + 3                # tf from the new node
    while robot.base_pose().planar_distance(live["sim"].base_pose()) > 1e-3 and \
            time.monotonic() < t_end:
        time.sleep(0.05)
    assert robot.base_pose().planar_distance(live["sim"].base_pose()) < 1e-3


def test_a_dead_endpoint_is_one_line_and_exit_2(capsys):
    from hearth.cli.main import main
    t0 = time.monotonic()
    rc = main(["run", "go_to_rest", "--no-save", "--ros2", _free_endpoint(),
               "--topics", "connect_timeout=1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith("no ROS 2 robot at tcp/127.0.0.1:")
    assert "nothing answers there" in err[0]
    assert time.monotonic() - t0 < 15


def test_a_lost_link_fails_the_running_goal_with_one_line(live):
    """Last: the robot goes (its node closes, its liveliness tokens vanish)."""
    robot, server, sim = live["robot"], live["server"], live["sim"]
    belief = live["sc"].belief
    goal = max((pose for o in belief.large_objects() for _, pose in belief.parking_positions(o.id)),
               key=lambda pose: pose.planar_distance(sim.base_pose()))
    before = set(server.nav.goals)
    act = robot.navigate_to(goal)
    t_end = time.monotonic() + 5
    new: list = []
    while not (new and new[0]["status"] == EXECUTING) and time.monotonic() < t_end:
        new = [g for k, g in server.nav.goals.items() if k not in before]
        time.sleep(0.02)
    assert act.status() == "running"
    server.close()
    t0 = time.monotonic()
    while act.status() == "running" and time.monotonic() - t0 < 10:
        time.sleep(0.02)
    assert act.status() == "failed"
    assert act.reason.startswith("lost the link to the robot: its NavigateToPose server")
    assert time.monotonic() - t0 < 5
    assert robot.link_lost() == act.reason
    from hearth.robot.errors import RobotError
    with pytest.raises(RobotError, match="lost the link"):
        robot.capture()
