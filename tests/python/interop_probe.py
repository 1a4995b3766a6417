#!/usr/bin/env python3
"""The rclpy side of tests/rclpy_interop.rs: a plain rclpy node that watches the rover graph.

Started before the graph: it imports everything, writes OUT.ready and waits for the file OUT.go, which
the test creates once every node is active; only then does it join the DDS domain, so the discovery
figures leave out Python's start-up. It subscribes to every topic of the graph (docs/architecture.md), then, while the graph
runs against the headless simulator:
  * records the wall-clock time of the first message on every graph topic (discovery figures),
  * checks the content of the messages (decodable JPEGs, image sizes, frame ids, finite numbers,
    the 200x200 map, ...),
  * checks the graph: every node, and every topic with its type and its publishing node, from a
    second participant created on the running graph, as a `ros2` tool started now would be (the
    probe's own participant's view is reported as a note),
  * joins the latched `map` late and expects the last map at once,
  * reads and sets a bridge parameter through the rcl_interfaces services, and expects unknown,
    ill-typed and out-of-range values to be refused,
  * drives the rover over `cmd_vel` and checks that the simulator applies the teleop command
    while it is fresh, and the decision node's command again once it is stale.
Everything found is written to OUT as JSON; the Rust test asserts on it.
"""

import argparse
import io
import json
import math
import os
import sys
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseArray, Twist
from nav_msgs.msg import OccupancyGrid, Odometry
from PIL import Image as PilImage
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, ListParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rover_msgs.msg import DecisionState, DriveCommand, MapStats, PickupRequest, Telemetry, TerrainScan
from sensor_msgs.msg import CameraInfo, CompressedImage, Image
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

WIDTH, HEIGHT = 320, 160
MAP_SIDE = 200
CAMERA_FRAME = "camera_optical_frame"
MODES = {"explore", "approach_sample", "pickup", "recover", "return_home", "done"}
# How many problems of one topic are kept for the report.
MAX_PROBLEMS = 5
# Applied command values are sent as 4-decimal strings by the simulator.
VALUE_TOLERANCE = 2e-3


class GraphTopic:
    """A topic of the graph: its type, the node at its other end, whether it is latched, and
    whether it is one of the lock-step loop's per-frame topics, which the graph reads best effort."""

    def __init__(self, name, msg_type, publisher=None, subscriber=None, latched=False, timed=True, per_frame=False):
        self.name = name
        self.msg_type = msg_type
        self.type_name = f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"
        self.publisher = publisher
        self.subscriber = subscriber
        self.latched = latched
        self.per_frame = per_frame
        # Whether its first message counts in the discovery figures (published continuously).
        self.timed = timed

    @property
    def absolute(self):
        return self.name if self.name.startswith("/") else "/" + self.name


TOPICS = [
    GraphTopic("camera/image_raw/compressed", CompressedImage, publisher="bridge", subscriber="perception", per_frame=True),
    GraphTopic("camera/image_raw", Image, publisher="bridge"),
    GraphTopic("camera/camera_info", CameraInfo, publisher="bridge"),
    GraphTopic("odom", Odometry, publisher="bridge"),
    GraphTopic("/tf", TFMessage, publisher="bridge"),
    GraphTopic("rover/telemetry", Telemetry, publisher="bridge", subscriber="pickup", per_frame=True),
    GraphTopic("sim/sample_truth", PoseArray, publisher="bridge", latched=True),
    GraphTopic("rover/terrain", TerrainScan, publisher="perception", subscriber="decision", per_frame=True),
    GraphTopic("rover/vision", Image, publisher="perception", subscriber="bridge"),
    GraphTopic("map", OccupancyGrid, publisher="mapping", subscriber="decision", latched=True),
    GraphTopic("map/image", Image, publisher="mapping", subscriber="bridge"),
    GraphTopic("rover/map_stats", MapStats, publisher="mapping"),
    GraphTopic("rover/rocks", PoseArray, publisher="mapping", subscriber="decision"),
    GraphTopic("rover/sample_markers", MarkerArray, publisher="mapping", latched=True),
    GraphTopic("rover/drive_cmd", DriveCommand, publisher="decision", subscriber="bridge", per_frame=True),
    GraphTopic("rover/pickup", PickupRequest, publisher="pickup", subscriber="bridge", timed=False),
    GraphTopic("rover/mode", DecisionState, publisher="decision"),
    GraphTopic("cmd_vel", Twist, subscriber="bridge", timed=False),
    GraphTopic("/diagnostics", DiagnosticArray, publisher="bridge"),
]


def finite(*values):
    return all(math.isfinite(v) for v in values)


def stamp_key(header):
    return (header.stamp.sec, header.stamp.nanosec)


def stamp_is_set(header):
    return header.stamp.sec > 0


def unit_quaternion(q):
    return finite(q.x, q.y, q.z, q.w) and abs(math.sqrt(q.x**2 + q.y**2 + q.z**2 + q.w**2) - 1.0) < 1e-3


def header_problems(header, frame_id):
    problems = []
    if header.frame_id != frame_id:
        problems.append(f"frame_id {header.frame_id!r}, expected {frame_id!r}")
    if not stamp_is_set(header):
        problems.append("header stamp not set")
    return problems


def rgb8_problems(msg, width=None, height=None):
    problems = []
    if msg.encoding != "rgb8":
        problems.append(f"encoding {msg.encoding!r}")
    if width is not None and (msg.width, msg.height) != (width, height):
        problems.append(f"size {msg.width}x{msg.height}, expected {width}x{height}")
    if msg.step != msg.width * 3 or len(msg.data) != msg.width * msg.height * 3 or msg.width == 0:
        problems.append(f"{len(msg.data)} bytes, step {msg.step} for {msg.width}x{msg.height}")
    return problems


def decode_jpeg(data):
    image = PilImage.open(io.BytesIO(bytes(data)))
    if image.format != "JPEG":
        raise ValueError(f"format {image.format}")
    return np.asarray(image.convert("RGB"))


class Probe:
    """Subscribes to the graph and keeps what the checks need."""

    def __init__(self, node):
        self.node = node
        self.first_at = {}
        self.counts = {t.absolute: 0 for t in TOPICS}
        self.problems = {t.absolute: [] for t in TOPICS}
        self.jpegs = {}
        self.jpegs_decoded = 0
        self.raw_compared = []
        self.odom_by_stamp = {}
        self.tf_matched = 0
        self.telemetry = {}
        self.drive = {}
        self.maps = []
        self.most_spheres = 0
        self.last_diagnostics = {}
        self.checkers = {
            "/camera/image_raw/compressed": self.check_compressed,
            "/camera/image_raw": self.check_raw,
            "/camera/camera_info": self.check_camera_info,
            "/odom": self.check_odom,
            "/tf": self.check_tf,
            "/rover/telemetry": self.check_telemetry,
            "/sim/sample_truth": self.check_sample_truth,
            "/rover/terrain": self.check_terrain,
            "/rover/vision": lambda m: rgb8_problems(m),
            "/map": self.check_map,
            "/map/image": lambda m: rgb8_problems(m),
            "/rover/map_stats": self.check_map_stats,
            "/rover/rocks": self.check_rocks,
            "/rover/sample_markers": self.check_sample_markers,
            "/rover/drive_cmd": self.check_drive,
            "/rover/pickup": lambda m: header_problems(m.header, "base_link"),
            "/rover/mode": self.check_mode,
            "/diagnostics": self.check_diagnostics,
        }
        for topic in TOPICS:
            if topic.publisher:
                node.create_subscription(topic.msg_type, topic.absolute, self.receiver(topic), qos_of(topic))

    def receiver(self, topic):
        name = topic.absolute

        def on_message(msg):
            self.first_at.setdefault(name, time.time())
            self.counts[name] += 1
            try:
                found = self.checkers[name](msg)
            except Exception as e:  # a malformed message must show up as a problem, not stop the probe
                found = [f"check raised {type(e).__name__}: {e}"]
            if found and len(self.problems[name]) < MAX_PROBLEMS:
                self.problems[name].append("; ".join(found))

        return on_message

    # ---- content checks, one per topic; each returns a list of problems ----

    def check_compressed(self, msg):
        problems = header_problems(msg.header, CAMERA_FRAME)
        if "jpeg" not in msg.format.lower():
            problems.append(f"format {msg.format!r}")
        count = self.counts["/camera/image_raw/compressed"]
        if count <= 20 or count % 25 == 0:
            pixels = decode_jpeg(msg.data)
            self.jpegs_decoded += 1
            if pixels.shape != (HEIGHT, WIDTH, 3):
                problems.append(f"decoded shape {pixels.shape}")
            if len(self.jpegs) < 40:
                self.jpegs[stamp_key(msg.header)] = pixels
        return problems

    def check_raw(self, msg):
        problems = header_problems(msg.header, CAMERA_FRAME) + rgb8_problems(msg, WIDTH, HEIGHT)
        jpeg = self.jpegs.pop(stamp_key(msg.header), None)
        if jpeg is not None and not problems:
            raw = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(HEIGHT, WIDTH, 3)
            difference = float(np.abs(raw.astype(np.int16) - jpeg.astype(np.int16)).mean())
            self.raw_compared.append(difference)
            if difference > 4.0:
                problems.append(f"differs from the JPEG of the same stamp by {difference:.2f} per channel")
        return problems

    def check_camera_info(self, msg):
        problems = header_problems(msg.header, CAMERA_FRAME)
        if (msg.width, msg.height) != (WIDTH, HEIGHT):
            problems.append(f"size {msg.width}x{msg.height}")
        fx, cx, fy, cy = msg.k[0], msg.k[2], msg.k[4], msg.k[5]
        if not (finite(*msg.k) and fx > 0 and abs(fx - fy) < 1e-6):
            problems.append(f"K {list(msg.k)}")
        if abs(cx - (WIDTH - 1) / 2) > 1 or abs(cy - (HEIGHT - 1) / 2) > 1:
            problems.append(f"principal point ({cx}, {cy})")
        if list(msg.p)[:3] != list(msg.k)[:3]:
            problems.append("P does not carry K")
        return problems

    def check_odom(self, msg):
        problems = header_problems(msg.header, "odom")
        if msg.child_frame_id != "base_link":
            problems.append(f"child_frame_id {msg.child_frame_id!r}")
        p = msg.pose.pose.position
        if not (finite(p.x, p.y, p.z, msg.twist.twist.linear.x) and 0 <= p.x <= MAP_SIDE and 0 <= p.y <= MAP_SIDE):
            problems.append(f"position ({p.x}, {p.y}, {p.z})")
        if not unit_quaternion(msg.pose.pose.orientation):
            problems.append("orientation is not a unit quaternion")
        if len(self.odom_by_stamp) < 200:
            self.odom_by_stamp[stamp_key(msg.header)] = (p.x, p.y)
        return problems

    def check_tf(self, msg):
        if len(msg.transforms) != 1:
            return [f"{len(msg.transforms)} transforms"]
        t = msg.transforms[0]
        problems = header_problems(t.header, "odom")
        if t.child_frame_id != "base_link":
            problems.append(f"child_frame_id {t.child_frame_id!r}")
        if not unit_quaternion(t.transform.rotation):
            problems.append("rotation is not a unit quaternion")
        odom = self.odom_by_stamp.get(stamp_key(t.header))
        if odom is not None:
            self.tf_matched += 1
            if abs(odom[0] - t.transform.translation.x) > 1e-9 or abs(odom[1] - t.transform.translation.y) > 1e-9:
                problems.append(f"translation differs from odom of the same stamp {odom}")
        return problems

    def check_telemetry(self, msg):
        problems = header_problems(msg.header, "odom")
        values = (msg.x_m, msg.y_m, msg.yaw_rad, msg.pitch_rad, msg.roll_rad, msg.speed_mps, msg.throttle, msg.brake)
        if not finite(*values, msg.steering_angle_deg):
            problems.append(f"non-finite value in {values}")
        if not (0 <= msg.x_m <= MAP_SIDE and 0 <= msg.y_m <= MAP_SIDE and abs(msg.steering_angle_deg) <= 15):
            problems.append(f"out of range: position ({msg.x_m}, {msg.y_m}), steering {msg.steering_angle_deg}")
        if not 0 <= msg.samples_remaining <= 6:
            problems.append(f"samples_remaining {msg.samples_remaining}")
        if msg.frame in self.telemetry:
            problems.append(f"frame {msg.frame} seen twice")
        self.telemetry[msg.frame] = (
            time.time(), msg.throttle, msg.brake, msg.steering_angle_deg, msg.speed_mps, msg.picking_up
        )
        return problems

    def check_sample_truth(self, msg):
        problems = header_problems(msg.header, "map")
        if not 1 <= len(msg.poses) <= 6:
            problems.append(f"{len(msg.poses)} samples")
        for pose in msg.poses:
            if not (finite(pose.position.x, pose.position.y) and 0 <= pose.position.x <= MAP_SIDE):
                problems.append(f"sample at ({pose.position.x}, {pose.position.y})")
        return problems

    def check_terrain(self, msg):
        problems = header_problems(msg.header, "base_link")
        if len(msg.cells) != msg.rows * msg.cols or msg.rows == 0:
            problems.append(f"{len(msg.cells)} cells for {msg.rows}x{msg.cols}")
        elif max(msg.cells) > TerrainScan.ROCK:
            problems.append(f"cell class {max(msg.cells)}")
        if not (finite(msg.telemetry.x_m, msg.telemetry.y_m, msg.telemetry.yaw_rad, msg.resolution_m) and msg.resolution_m > 0):
            problems.append("non-finite pose or resolution")
        if msg.navigable_count and not finite(msg.navigable_bearing_rad, msg.navigable_distance_m):
            problems.append("non-finite navigable summary")
        return problems

    def check_map(self, msg):
        problems = header_problems(msg.header, "map")
        info = msg.info
        if (info.width, info.height, info.resolution) != (MAP_SIDE, MAP_SIDE, 1.0):
            problems.append(f"{info.width}x{info.height} cells of {info.resolution} m")
        if (info.origin.position.x, info.origin.position.y) != (0.0, 0.0):
            problems.append(f"origin ({info.origin.position.x}, {info.origin.position.y})")
        if len(msg.data) != MAP_SIDE * MAP_SIDE:
            problems.append(f"{len(msg.data)} cells")
        values = set(np.unique(np.asarray(msg.data, dtype=np.int8)).tolist())
        if not values <= {-1, 0, 100}:
            problems.append(f"cell values {sorted(values)}")
        self.maps.append((time.time(), int(np.count_nonzero(np.asarray(msg.data) >= 0))))
        return problems

    def check_map_stats(self, msg):
        problems = header_problems(msg.header, "map")
        for name in ("mapped_pct", "fidelity_pct"):
            value = getattr(msg, name)
            if not (math.isnan(value) or 0 <= value <= 100):
                problems.append(f"{name} {value}")
        if msg.navigable_cells + msg.obstacle_cells > MAP_SIDE * MAP_SIDE:
            problems.append(f"{msg.navigable_cells} + {msg.obstacle_cells} cells")
        return problems

    def check_rocks(self, msg):
        problems = header_problems(msg.header, "map")
        for pose in msg.poses:
            p = pose.position
            if not (finite(p.x, p.y) and 0 <= p.x <= MAP_SIDE and 0 <= p.y <= MAP_SIDE):
                problems.append(f"rock at ({p.x}, {p.y})")
        return problems

    def check_sample_markers(self, msg):
        """A DELETEALL first, then a sphere in the map per located rock or collected sample."""
        if not msg.markers or msg.markers[0].action != Marker.DELETEALL:
            return ["the first marker is not a DELETEALL"]
        problems = []
        self.most_spheres = max(self.most_spheres, len(msg.markers) - 1)
        for marker in msg.markers[1:]:
            problems += header_problems(marker.header, "map")
            p = marker.pose.position
            if marker.ns not in ("located", "collected") or marker.type != Marker.SPHERE or marker.action != Marker.ADD:
                problems.append(f"marker {marker.ns!r} {marker.id}: type {marker.type}, action {marker.action}")
            elif not (finite(p.x, p.y) and 0 <= p.x <= MAP_SIDE and 0 <= p.y <= MAP_SIDE):
                problems.append(f"marker {marker.ns!r} {marker.id} at ({p.x}, {p.y})")
        return problems

    def check_drive(self, msg):
        problems = header_problems(msg.header, "base_link")
        if not finite(msg.throttle, msg.brake, msg.steering_angle_deg):
            problems.append("non-finite command")
        elif not (-1 <= msg.throttle <= 1 and msg.brake >= 0 and abs(msg.steering_angle_deg) <= 15):
            problems.append(f"out of range: {msg.throttle}, {msg.brake}, {msg.steering_angle_deg}")
        self.drive[msg.frame] = (msg.throttle, msg.brake, msg.steering_angle_deg)
        return problems

    def check_mode(self, msg):
        problems = header_problems(msg.header, "map")
        if msg.mode not in MODES:
            problems.append(f"mode {msg.mode!r}")
        return problems

    def check_diagnostics(self, msg):
        if len(msg.status) != 1:
            return [f"{len(msg.status)} statuses"]
        status = msg.status[0]
        problems = []
        if "bridge" not in status.name:
            problems.append(f"status name {status.name!r}")
        values = {kv.key: kv.value for kv in status.values}
        for key in ("link_up", "telemetry_rate_hz", "reply_latency_p50_ms", "deadline_misses", "replies_teleop"):
            if key not in values:
                problems.append(f"no {key}")
        self.last_diagnostics = values
        return problems

    # ---- derived results ----

    def applied_matches_decision(self, frame):
        """Whether the command the simulator applied after `frame` is the decision node's: the one
        for `frame`, or the one before when the bridge held the last command past its deadline."""
        applied = self.telemetry.get(frame + 1)
        decided = [self.drive[f] for f in (frame, frame - 1) if f in self.drive]
        if applied is None or not decided:
            return None
        return any(all(abs(a - b) <= VALUE_TOLERANCE for a, b in zip(applied[1:4], d)) for d in decided)


def qos_of(topic):
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1 if topic.latched else 50,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if topic.latched else DurabilityPolicy.VOLATILE,
    )


def spin(node, seconds, until=lambda: False):
    end = time.monotonic() + seconds
    while time.monotonic() < end and not until():
        rclpy.spin_once(node, timeout_sec=0.02)
    return until()


class Report:
    """Named checks with their outcome, written as JSON."""

    def __init__(self):
        self.checks = {}

    def record(self, name, ok, detail):
        self.checks[name] = {"ok": bool(ok), "detail": str(detail)}
        print(f"probe: {'ok  ' if ok else 'FAIL'} {name}: {detail}", file=sys.stderr, flush=True)


# ---- phases ----


def wait_for_first_messages(node, probe, timeout_s):
    timed = [t.absolute for t in TOPICS if t.timed]
    spin(node, timeout_s, lambda: all(name in probe.first_at for name in timed))
    return [name for name in timed if name not in probe.first_at]


def graph_mismatches(node, nodes):
    """What the ROS graph lacks compared to the topic table: the names `nodes`, topic types, endpoints."""
    found = []
    names = {name for name, ns in node.get_node_names_and_namespaces() if ns == "/"}
    found += [f"node /{n} missing" for n in nodes if n not in names]
    for topic in TOPICS:
        for role, wanted, infos in (
            ("publisher", topic.publisher, node.get_publishers_info_by_topic(topic.absolute)),
            ("subscription", topic.subscriber, node.get_subscriptions_info_by_topic(topic.absolute)),
        ):
            if wanted is None:
                continue
            ends = [i for i in infos if i.node_name == wanted and i.node_namespace == "/"]
            if not ends:
                found.append(f"{topic.absolute}: no {role} of /{wanted}")
            for end in ends:
                if end.topic_type != topic.type_name:
                    found.append(f"{topic.absolute}: /{wanted} uses {end.topic_type}, expected {topic.type_name}")
                reliability = end.qos_profile.reliability
                if role == "subscription" and topic.per_frame:
                    if reliability != ReliabilityPolicy.BEST_EFFORT:
                        found.append(f"{topic.absolute}: {role} of /{wanted} is {reliability.name}, expected BEST_EFFORT")
                elif reliability != ReliabilityPolicy.RELIABLE:
                    found.append(f"{topic.absolute}: {role} of /{wanted} is {reliability.name}, expected RELIABLE")
                if role == "publisher" and topic.latched and end.qos_profile.durability != DurabilityPolicy.TRANSIENT_LOCAL:
                    found.append(f"{topic.absolute}: publisher is not transient local")
    types = dict(node.get_topic_names_and_types())
    for topic in TOPICS:
        if types.get(topic.absolute) != [topic.type_name]:
            found.append(f"{topic.absolute}: graph types {types.get(topic.absolute)}")
    return found


def settled_graph_mismatches(node, nodes, executor, timeout_s):
    """Graph mismatches once they are gone or `timeout_s` has passed."""
    mismatches = graph_mismatches(node, nodes)
    deadline = time.monotonic() + timeout_s
    while mismatches and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.1)
        mismatches = graph_mismatches(node, nodes)
    return mismatches


class ToolParticipant:
    """A second rclpy context, as a tool started on the running graph (`ros2 node list`,
    `ros2 param set`) has: the graph and parameter checks use it."""

    def __init__(self):
        self.context = rclpy.Context()
        rclpy.init(args=[sys.argv[0]], context=self.context)
        self.node = Node("interop_probe_tool", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def check_graph(probe_node, tool, nodes, report, notes):
    """The graph of the node names `nodes` as the tool sees it; how the probe's own participant,
    which joined with the nodes, sees it is a note (see the module docstring)."""
    mismatches = settled_graph_mismatches(tool.node, nodes, tool.executor, 8.0)
    report.record("graph", not mismatches, "; ".join(mismatches) or f"{len(nodes)} nodes, {len(TOPICS)} topics as designed")
    notes["graph_seen_by_early_participant"] = "; ".join(graph_mismatches(probe_node, nodes)) or "complete"


def check_late_map(node, probe, report):
    """A subscription created after the map was published gets the last map at once."""
    received = []
    first_map_at = probe.first_at.get("/map")
    topic = next(t for t in TOPICS if t.absolute == "/map")
    created = time.time()
    subscription = node.create_subscription(OccupancyGrid, "/map", received.append, qos_of(topic))
    spin(node, 5.0, lambda: received)
    node.destroy_subscription(subscription)
    if not received or first_map_at is None:
        report.record("map_late_join", False, f"no map within 5 s of a late subscription (first map at {first_map_at})")
        return
    msg = received[0]
    problems = probe.check_map(msg)
    latency = time.time() - created if len(received) == 1 else None
    detail = (
        f"subscribed {created - first_map_at:.2f} s after the first map, got a "
        f"{msg.info.width}x{msg.info.height} map with {probe.maps[-1][1]} known cells"
        + (f" after {latency * 1000:.0f} ms" if latency is not None else "")
    )
    report.record("map_late_join", created > first_map_at and not problems, "; ".join(problems) or detail)


class ParameterClient:
    """The standard parameter services of a remote node."""

    def __init__(self, tool, target):
        node = tool.node
        self.executor = tool.executor
        self.get = node.create_client(GetParameters, f"/{target}/get_parameters")
        self.set = node.create_client(SetParameters, f"/{target}/set_parameters")
        self.list = node.create_client(ListParameters, f"/{target}/list_parameters")

    def call(self, client, request, attempts=3):
        if not client.wait_for_service(timeout_sec=5.0):
            raise RuntimeError(f"service {client.srv_name} not available")
        for _ in range(attempts):
            future = client.call_async(request)
            self.executor.spin_until_future_complete(future, timeout_sec=2.0)
            if future.done():
                return future.result()
            client.remove_pending_request(future)
        raise RuntimeError(f"no response from {client.srv_name}")

    def get_value(self, name):
        values = self.call(self.get, GetParameters.Request(names=[name])).values
        return values[0] if values else None

    def set_value(self, name, value):
        request = SetParameters.Request(parameters=[Parameter(name=name, value=value)])
        return self.call(self.set, request).results[0]


def double_value(x):
    return ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=x)


def string_value(text):
    return ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=text)


def check_parameters(tool, report, teleop_timeout_ms):
    """Reads, sets and fails to set parameters of the running bridge."""
    client = ParameterClient(tool, "bridge")
    name = "teleop_timeout_ms"
    names = client.call(client.list, ListParameters.Request()).result.names
    report.record("params_list", name in names and "port" in names, f"/bridge lists {sorted(names)}")
    before = client.get_value(name)
    report.record(
        "params_get",
        before is not None and before.type == ParameterType.PARAMETER_DOUBLE and before.double_value == 500.0,
        f"{name} = {before.double_value if before else None} (type {before.type if before else None})",
    )
    result = client.set_value(name, double_value(teleop_timeout_ms))
    after = client.get_value(name)
    report.record(
        "params_set",
        result.successful and after is not None and after.double_value == teleop_timeout_ms,
        f"set {name} := {teleop_timeout_ms}: successful={result.successful} {result.reason!r}; "
        f"read back {after.double_value if after else None}",
    )
    refusals = {
        "params_refuse_unknown": ("no_such_parameter", double_value(1.0)),
        "params_refuse_type": (name, string_value("fast")),
        "params_refuse_range": (name, double_value(-5.0)),
    }
    for check, (param, value) in refusals.items():
        refused = client.set_value(param, value)
        report.record(check, not refused.successful and refused.reason, f"set {param}: reason {refused.reason!r}")
    unchanged = client.get_value(name)
    report.record(
        "params_unchanged_after_refusals",
        unchanged is not None and unchanged.double_value == teleop_timeout_ms,
        f"{name} = {unchanged.double_value if unchanged else None}",
    )


def twist(linear_x, angular_z):
    message = Twist()
    message.linear.x = float(linear_x)
    message.angular.z = float(angular_z)
    return message


def drive_over_cmd_vel(node, publisher, command, seconds):
    """Publishes `command` at 20 Hz for `seconds`; returns (start, end) wall-clock times."""
    start = time.time()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        publisher.publish(command)
        spin(node, 0.05)
    return start, time.time()


def frames_between(probe, start, end):
    return [(f, v) for f, v in sorted(probe.telemetry.items()) if start <= v[0] <= end]


def check_teleop_phase(probe, report, name, window, expectation, settle_s):
    """`expectation(applied commands, speeds)` over the frames from `settle_s` into the window."""
    frames = frames_between(probe, window[0] + settle_s, window[1])
    if len(frames) < 5:
        report.record(f"teleop_{name}", False, f"only {len(frames)} telemetry frames while driving")
        return frames
    if any(v[5] for _, v in frames):
        report.record(f"teleop_{name}", False, "a sample pickup froze the rover meanwhile (try another seed)")
        return frames
    applied = [v[1:4] for _, v in frames]
    speeds = [v[4] for _, v in frames]
    ok, detail = expectation(applied, speeds)
    report.record(f"teleop_{name}", ok, f"{len(frames)} frames: {detail}")
    return frames


def steering_follows(sign):
    def expectation(applied, speeds):
        steering = [s for _, _, s in applied]
        agreeing = sum(1 for s in steering if s * sign >= 5.0)
        moving = max(speeds) > 0.2
        return (
            agreeing >= 0.8 * len(steering) and moving,
            f"steering {min(steering):.1f}..{max(steering):.1f} deg ({agreeing} on the commanded side), "
            f"top speed {max(speeds):.2f} m/s",
        )

    return expectation


def stops(applied, speeds):
    braking = sum(1 for _, b, _ in applied if b > 0)
    return (
        braking > 0 and speeds[0] > 0.3 and abs(speeds[-1]) < 0.3,
        f"{braking} frames braking, speed {speeds[0]:.2f} -> {speeds[-1]:.2f} m/s",
    )


def reverses(applied, speeds):
    throttles = [t for t, _, _ in applied]
    backwards = sum(1 for t in throttles if t < 0)
    return (
        backwards >= 0.8 * len(throttles) and min(speeds) < -0.05,
        f"throttle {min(throttles):.2f}..{max(throttles):.2f} ({backwards} reversing), lowest speed {min(speeds):.2f} m/s",
    )


def check_teleop(node, probe, report, teleop_timeout_s):
    publisher = node.create_publisher(Twist, "/cmd_vel", 10)
    spin(node, 3.0, lambda: publisher.get_subscription_count() > 0)
    phases = [
        ("left", twist(0.8, 0.6), 2.5, steering_follows(+1), 0.5),
        ("stop", twist(0.0, 0.0), 1.5, stops, 0.0),
        ("right", twist(0.8, -0.6), 1.5, steering_follows(-1), 0.5),
        ("reverse", twist(-0.6, 0.0), 2.0, reverses, 0.5),
    ]
    teleop_frames = []
    last_sent = None
    for name, command, seconds, expectation, settle_s in phases:
        window = drive_over_cmd_vel(node, publisher, command, seconds)
        last_sent = window[1]
        teleop_frames += check_teleop_phase(probe, report, name, window, expectation, settle_s)
    spin(node, teleop_timeout_s + 2.5)
    overridden = [probe.applied_matches_decision(f) for f, _ in teleop_frames]
    matching = sum(1 for m in overridden if m)
    teleop_replies = int(probe.last_diagnostics.get("replies_teleop", "0"))
    report.record(
        "teleop_overrides_decision",
        overridden and matching <= 0.2 * len(overridden) and teleop_replies > 0,
        f"{matching} of {len(overridden)} teleop frames applied the decision node's command; "
        f"/diagnostics replies_teleop = {teleop_replies}",
    )
    check_release(probe, report, last_sent, teleop_timeout_s)


def check_release(probe, report, last_sent, teleop_timeout_s):
    """Once cmd_vel is stale (after the bridge's teleop timeout), the decision node drives again."""
    after = [(f, v[0]) for f, v in sorted(probe.telemetry.items()) if v[0] > last_sent]
    released_at = next((t for f, t in after if probe.applied_matches_decision(f - 1)), None)
    if released_at is None:
        report.record("teleop_release", False, f"the decision node's commands were not applied again in {len(after)} frames")
        return
    delay = released_at - last_sent
    following = [probe.applied_matches_decision(f - 1) for f, t in after if released_at <= t <= released_at + 1.0]
    share = sum(1 for m in following if m) / max(1, len(following))
    report.record(
        "teleop_release",
        teleop_timeout_s - 0.2 <= delay <= teleop_timeout_s + 1.0 and share >= 0.8,
        f"decision in control {delay:.2f} s after the last cmd_vel (teleop_timeout {teleop_timeout_s:.1f} s); "
        f"{share:.0%} of the next second's frames applied its command",
    )


def content_results(probe, report):
    for topic in TOPICS:
        if not topic.publisher:
            continue
        name = topic.absolute
        count = probe.counts[name]
        problems = probe.problems[name]
        received = count > 0 or not topic.timed
        detail = f"{count} messages" + (f", at most {probe.most_spheres} spheres" if name == "/rover/sample_markers" else "")
        report.record(f"content {name}", received and not problems, "; ".join(problems) or detail)
    report.record(
        "content jpeg decoding",
        probe.jpegs_decoded > 0 and len(probe.raw_compared) > 0 and probe.tf_matched > 0,
        f"{probe.jpegs_decoded} JPEGs decoded to {WIDTH}x{HEIGHT}, {len(probe.raw_compared)} raw images compared "
        f"(mean difference {np.mean(probe.raw_compared) if probe.raw_compared else float('nan'):.2f}), "
        f"{probe.tf_matched} /tf transforms matched to odom",
    )
    known = [cells for _, cells in probe.maps]
    report.record("content map grows", known and known[-1] > known[0], f"known cells {known[0] if known else None} -> {known[-1] if known else None}")


def wait_for_go(path, timeout_s=60.0):
    """Waits until the test has started the graph (it creates `path`)."""
    deadline = time.monotonic() + timeout_s
    while not os.path.exists(path):
        if time.monotonic() > deadline:
            sys.exit(f"probe: {path} did not appear within {timeout_s:g} s")
        time.sleep(0.005)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="the JSON report")
    parser.add_argument("--nodes", required=True, help="the graph's node names, comma-separated (`rover nodes`)")
    parser.add_argument("--first-message-timeout", type=float, default=10.0)
    parser.add_argument("--teleop-timeout-ms", type=float, default=1500.0, help="bridge teleop_timeout_ms to set")
    args = parser.parse_args()

    with open(args.out + ".ready", "w") as ready:
        ready.write("imported\n")
    wait_for_go(args.out + ".go")
    rclpy.init(args=[sys.argv[0]])
    node = Node("interop_probe")
    probe = Probe(node)
    report = Report()
    missing = wait_for_first_messages(node, probe, args.first_message_timeout)
    report.record("first_messages", not missing, f"nothing on {missing}" if missing else "every graph topic")
    notes = {}
    tool = ToolParticipant()
    check_graph(node, tool, args.nodes.split(","), report, notes)
    check_late_map(node, probe, report)
    try:
        check_parameters(tool, report, args.teleop_timeout_ms)
    except RuntimeError as e:
        report.record("params_services", False, e)
    tool.close()
    check_teleop(node, probe, report, args.teleop_timeout_ms / 1000.0)
    content_results(probe, report)
    with open(args.out, "w") as out:
        result = {"first_message_at": probe.first_at, "counts": probe.counts, "checks": report.checks, "notes": notes}
        json.dump(result, out, indent=1)
    node.destroy_node()
    rclpy.try_shutdown()


if __name__ == "__main__":
    main()
