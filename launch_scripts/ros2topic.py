#!/usr/bin/env python3
"""`ros2 topic list|echo|hz|info` and `ros2 node list` for machines without the ros2 command line.

The ROS 2 wheels on PyPI bring rclpy and the message packages but neither ros2cli nor
rosidl_runtime_py, so this tool does the same with rclpy alone. Message types are resolved from
the graph (e.g. rover_msgs/msg/Telemetry) and imported from their Python packages: run
`source tools/ros-env.sh` first so rclpy and rover_msgs are on the path. ROS_DOMAIN_ID selects the
domain, as for every ROS 2 program.
"""

import argparse
import importlib
import math
import os
import sys
import time

import yaml

MISSING_RCLPY = (
    "rclpy is not importable: run tools/setup-ros once, then `source tools/ros-env.sh`"
)

try:
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
except ImportError:
    sys.exit(f"error: {MISSING_RCLPY}")

# rmw's "infinite" duration, as the graph API reports it.
INFINITE_NS = 9223372036854775807


class CliError(Exception):
    """A user error: printed as `error: ...` with exit status 1."""


# ---------------------------------------------------------------------------------------------
# Graph helpers


def absolute_name(topic):
    """Topic names given relative are taken relative to the root namespace, as ros2cli does."""
    return topic if topic.startswith("/") else "/" + topic


def spin_for(node, seconds):
    """Processes the node's events for `seconds`."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=min(0.05, max(0.0, end - time.monotonic())))


def graph_snapshot(node):
    """Everything `list`, `info` and `node-list` show, to tell when discovery has settled."""
    topics = tuple(sorted((n, tuple(t)) for n, t in node.get_topic_names_and_types()))
    nodes = tuple(sorted(node.get_node_names_and_namespaces()))
    counts = tuple(
        (n, node.count_publishers(n), node.count_subscribers(n)) for n, _ in topics
    )
    return topics, nodes, counts


def wait_for_discovery(node, limit_s, quiet_s=0.5):
    """Spins until the graph has not changed for `quiet_s` (at most `limit_s`): a fresh
    participant has no daemon that already knows the graph."""
    deadline = time.monotonic() + limit_s
    last = graph_snapshot(node)
    stable_since = time.monotonic()
    while time.monotonic() < deadline:
        spin_for(node, 0.1)
        now = graph_snapshot(node)
        if now != last:
            last, stable_since = now, time.monotonic()
        elif time.monotonic() - stable_since >= quiet_s and now[0]:
            return


def topic_types(node, topic):
    return dict(node.get_topic_names_and_types()).get(topic, [])


def wait_for_publisher(node, topic, timeout_s):
    """Waits until `topic` has a publisher; returns its type name and the publishers' info."""
    deadline = time.monotonic() + timeout_s
    warned = False
    while True:
        publishers = node.get_publishers_info_by_topic(topic)
        types = topic_types(node, topic)
        if publishers and types:
            if len(types) > 1:
                raise CliError(f"topic {topic} has more than one type ({', '.join(types)}): pass TYPE")
            return types[0], publishers
        if time.monotonic() >= deadline:
            raise CliError(
                f"unknown topic '{topic}': no publisher appeared within {timeout_s:g} s "
                "(see `ros2topic.py list`, check ROS_DOMAIN_ID, or pass TYPE to wait for it)"
            )
        if not warned and time.monotonic() > deadline - timeout_s + 1.0:
            print(f"WARNING: topic [{topic}] does not appear to be published yet", file=sys.stderr)
            warned = True
        spin_for(node, 0.1)


def message_class(type_name):
    """The Python class of a message type name such as `rover_msgs/msg/Telemetry`."""
    parts = type_name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or parts[1] != "msg" or not all(parts):
        raise CliError(f"'{type_name}' is not a message type name (expected package/msg/Name)")
    package, _, name = parts
    try:
        module = importlib.import_module(f"{package}.msg")
    except ImportError:
        raise CliError(
            f"message type '{type_name}': Python package '{package}' is not importable "
            "(is it built, and did you `source tools/ros-env.sh`?)"
        ) from None
    cls = getattr(module, name, None)
    if cls is None or not hasattr(cls, "get_fields_and_field_types"):
        raise CliError(f"message type '{type_name}' does not exist in package '{package}'")
    return cls


def chosen_qos(publishers, args):
    """The subscription QoS: reliable and transient local only when every publisher offers it
    (as `ros2 topic echo` chooses), unless given on the command line."""
    reliable = all(p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in publishers)
    latched = bool(publishers) and all(
        p.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for p in publishers
    )
    reliability = ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT
    durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
    if args.qos_reliability:
        reliability = ReliabilityPolicy[args.qos_reliability.upper()]
    if args.qos_durability:
        durability = DurabilityPolicy[args.qos_durability.upper()]
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=args.qos_depth,
        reliability=reliability,
        durability=durability,
    )


# ---------------------------------------------------------------------------------------------
# Message to YAML


def field_path_value(message, path):
    """The value at `a.b.c` inside `message`."""
    value = message
    for part in path:
        if not hasattr(value, "get_fields_and_field_types") or part not in value.get_fields_and_field_types():
            raise CliError(f"invalid field '{'.'.join(path)}': no field '{part}'")
        value = getattr(value, part)
    return value


def sequence_summary(field_type, length):
    if field_type.startswith("sequence<"):
        return f"<sequence type: {field_type[len('sequence<'):-1]}, length: {length}>"
    return f"<array type: {field_type}, length: {length}>"


def plain_value(value, style, field_type=""):
    """Converts a message value into dicts, lists and scalars for YAML, truncating long strings
    and sequences as `ros2 topic echo` does."""
    if hasattr(value, "get_fields_and_field_types"):
        return {
            name: plain_value(getattr(value, name), style, kind)
            for name, kind in value.get_fields_and_field_types().items()
        }
    if isinstance(value, str):
        if style.no_str:
            return f"<string length: {len(value)}>"
        return value if len(value) <= style.limit else value[: style.limit] + "..."
    if isinstance(value, (bytes, bytearray)) and len(value) == 1:
        return value[0]
    if isinstance(value, (list, tuple, bytes, bytearray)) or type(value).__name__ in ("array", "ndarray"):
        items = list(value)
        if style.no_arr:
            return sequence_summary(field_type, len(items))
        element_type = field_type[len("sequence<"):-1] if field_type.startswith("sequence<") else field_type.split("[")[0]
        plain = [plain_value(v, style, element_type) for v in items[: style.limit]]
        return plain + ["..."] if len(items) > style.limit else plain
    if hasattr(value, "item"):
        return value.item()
    return value


def to_yaml(value):
    return yaml.safe_dump(value, default_flow_style=False, sort_keys=False, allow_unicode=True, width=10**9)


class Style:
    """How much of a message `echo` prints."""

    def __init__(self, args):
        self.limit = args.truncate_length
        self.no_arr = args.no_arr
        self.no_str = args.no_str


# ---------------------------------------------------------------------------------------------
# Subcommands


def run_list(node, args):
    wait_for_discovery(node, args.spin_time)
    topics = sorted(node.get_topic_names_and_types())
    if not args.include_hidden_topics:
        topics = [(n, t) for n, t in topics if not any(p.startswith("_") for p in n.split("/"))]
    if args.count_topics:
        print(len(topics))
        return 0
    for name, types in topics:
        print(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


def run_node_list(node, args):
    wait_for_discovery(node, args.spin_time)
    names = sorted(
        (ns.rstrip("/") + "/" + name)
        for name, ns in node.get_node_names_and_namespaces()
        if args.all or not name.startswith("_")
    )
    if args.count_nodes:
        print(len(names))
        return 0
    for name in names:
        print(name)
    return 0


def duration_text(duration):
    ns = duration.nanoseconds
    return "Infinite" if ns >= INFINITE_NS else f"{ns} nanoseconds"


def endpoint_text(info):
    qos = info.qos_profile
    gid = ".".join(f"{b:02x}" for b in info.endpoint_gid)
    return "\n".join(
        [
            f"Node name: {info.node_name}",
            f"Node namespace: {info.node_namespace}",
            f"Topic type: {info.topic_type}",
            f"Topic type hash: {info.topic_type_hash}",
            f"Endpoint type: {info.endpoint_type.name}",
            f"GID: {gid}",
            "QoS profile:",
            f"  Reliability: {qos.reliability.name}",
            f"  History (Depth): {qos.history.name} ({qos.depth})",
            f"  Durability: {qos.durability.name}",
            f"  Lifespan: {duration_text(qos.lifespan)}",
            f"  Deadline: {duration_text(qos.deadline)}",
            f"  Liveliness: {qos.liveliness.name}",
            f"  Liveliness lease duration: {duration_text(qos.liveliness_lease_duration)}",
            "",
        ]
    )


def run_info(node, args):
    topic = absolute_name(args.topic)
    wait_for_discovery(node, args.spin_time)
    types = topic_types(node, topic)
    if not types:
        raise CliError(f"Unknown topic '{topic}'")
    publishers = node.get_publishers_info_by_topic(topic)
    subscriptions = node.get_subscriptions_info_by_topic(topic)
    print(f"Type: {'; '.join(types)}")
    if args.verbose:
        print(f"\nPublisher count: {len(publishers)}\n")
        for info in publishers:
            print(endpoint_text(info))
        print(f"Subscription count: {len(subscriptions)}\n")
        for info in subscriptions:
            print(endpoint_text(info))
    else:
        print(f"Publisher count: {len(publishers)}")
        print(f"Subscription count: {len(subscriptions)}")
    return 0


def subscribe(node, args, callback):
    """Subscribes to the topic of `args` with the type and QoS it has in the graph."""
    topic = absolute_name(args.topic)
    if getattr(args, "message_type", None):
        cls = message_class(args.message_type)
        publishers = node.get_publishers_info_by_topic(topic)
    else:
        wait_for_discovery(node, min(args.timeout, 1.0))
        type_name, publishers = wait_for_publisher(node, topic, args.timeout)
        cls = message_class(type_name)
    node.create_subscription(cls, topic, callback, chosen_qos(publishers, args))
    return cls


def run_echo(node, args):
    wanted = 1 if args.once else args.times
    field = args.field.split(".") if args.field else []
    style = Style(args)
    printed = [0]

    def on_message(message):
        if wanted and printed[0] >= wanted:
            return
        print(to_yaml(plain_value(field_path_value(message, field), style)), end="")
        print("---", flush=True)
        printed[0] += 1

    cls = subscribe(node, args, on_message)
    field_path_value(cls(), field)
    while not wanted or printed[0] < wanted:
        rclpy.spin_once(node, timeout_sec=0.1)
    return 0


def rate_text(stamps, window):
    recent = stamps[-window:]
    gaps = [b - a for a, b in zip(recent, recent[1:])]
    mean = sum(gaps) / len(gaps)
    std = math.sqrt(sum((g - mean) ** 2 for g in gaps) / len(gaps))
    return (
        f"average rate: {1.0 / mean:.3f}\n"
        f"\tmin: {min(gaps):.3f}s max: {max(gaps):.3f}s std dev: {std:.5f}s window: {len(recent)}"
    )


def run_hz(node, args):
    stamps = []
    subscribe(node, args, lambda _message: stamps.append(time.monotonic()))
    started = time.monotonic()
    next_report = started + 1.0
    reported = 0
    while args.duration is None or time.monotonic() - started < args.duration:
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() < next_report:
            continue
        next_report += 1.0
        if len(stamps) > max(1, reported):
            print(rate_text(stamps, args.window), flush=True)
            reported = len(stamps)
        else:
            print("no new messages", flush=True)
    return 0


# ---------------------------------------------------------------------------------------------
# Command line


def positive_int(text):
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text} is not a positive whole number")
    return value


def positive_float(text):
    value = float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text} is not a positive number")
    return value


def add_discovery_option(parser):
    parser.add_argument(
        "--spin-time", type=positive_float, default=3.0, metavar="S",
        help="longest wait for discovery to settle, seconds (default 3)",
    )


def add_qos_options(parser):
    parser.add_argument(
        "--qos-durability", choices=["volatile", "transient_local"],
        help="durability of the subscription (default: transient_local if every publisher offers it)",
    )
    parser.add_argument(
        "--qos-reliability", choices=["reliable", "best_effort"],
        help="reliability of the subscription (default: reliable if every publisher offers it)",
    )
    parser.add_argument("--qos-depth", type=positive_int, default=10, metavar="N", help="queue depth (default 10)")
    parser.add_argument(
        "--timeout", type=positive_float, default=5.0, metavar="S",
        help="how long to wait for a publisher of the topic, seconds (default 5)",
    )


def parser():
    top = argparse.ArgumentParser(
        prog="ros2topic.py",
        description="ros2 topic list/echo/hz/info and ros2 node list, with rclpy alone. "
        "Honours ROS_DOMAIN_ID; run `source tools/ros-env.sh` first.",
    )
    commands = top.add_subparsers(dest="command", metavar="COMMAND", required=True)

    p = commands.add_parser("list", help="list the topics of the graph", description="List the topics of the graph.")
    p.add_argument("-t", "--show-types", action="store_true", help="also show each topic's type")
    p.add_argument("-c", "--count-topics", action="store_true", help="only print the number of topics")
    p.add_argument("--include-hidden-topics", action="store_true", help="also list hidden topics")
    add_discovery_option(p)
    p.set_defaults(run=run_list)

    p = commands.add_parser("echo", help="print the messages of a topic", description="Print the messages of a topic as YAML.")
    p.add_argument("topic", metavar="TOPIC", help="topic name, e.g. /rover/telemetry")
    p.add_argument("message_type", nargs="?", metavar="TYPE", help="message type, e.g. rover_msgs/msg/Telemetry (default: from the graph)")
    count = p.add_mutually_exclusive_group()
    count.add_argument("--once", action="store_true", help="print one message and exit")
    count.add_argument("-n", "--times", type=positive_int, default=0, metavar="N", help="print N messages and exit")
    p.add_argument("--field", metavar="A.B", help="print only this field of each message")
    p.add_argument("-l", "--truncate-length", type=positive_int, default=128, metavar="N", help="truncate strings and sequences to N items (default 128)")
    p.add_argument("--no-arr", action="store_true", help="print only the length of sequences")
    p.add_argument("--no-str", action="store_true", help="print only the length of strings")
    add_qos_options(p)
    p.set_defaults(run=run_echo)

    p = commands.add_parser("hz", help="print the rate of a topic", description="Print the rate of a topic every second.")
    p.add_argument("topic", metavar="TOPIC", help="topic name")
    p.add_argument("-w", "--window", type=positive_int, default=10000, metavar="N", help="messages the statistics are taken over (default 10000)")
    p.add_argument("--duration", type=positive_float, metavar="S", help="stop after S seconds (default: run until Ctrl-C)")
    add_qos_options(p)
    p.set_defaults(run=run_hz)

    p = commands.add_parser("info", help="print a topic's type, publishers and subscriptions", description="Print a topic's type and its publisher and subscription counts.")
    p.add_argument("topic", metavar="TOPIC", help="topic name")
    p.add_argument("-v", "--verbose", action="store_true", help="also list each endpoint with its node and QoS")
    add_discovery_option(p)
    p.set_defaults(run=run_info)

    p = commands.add_parser("node-list", help="list the nodes of the graph (ros2 node list)", description="List the nodes of the graph.")
    p.add_argument("-a", "--all", action="store_true", help="also list hidden nodes (names starting with _)")
    p.add_argument("-c", "--count-nodes", action="store_true", help="only print the number of nodes")
    add_discovery_option(p)
    p.set_defaults(run=run_node_list)
    return top


def main(argv):
    args = parser().parse_args(argv)
    rclpy.init(args=[sys.argv[0]])
    node = Node(f"_ros2topic_py_{os.getpid()}", start_parameter_services=False)
    try:
        return args.run(node, args)
    except CliError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except BrokenPipeError:
        sys.stderr.close()
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
