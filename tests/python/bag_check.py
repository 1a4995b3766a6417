#!/usr/bin/env python3
"""The Python side of tests/bag.rs: opens a bag of `rover bag record` with rosbags and rclpy.

Usage: bag_check.py BAG EXPECTED_JSON

EXPECTED_JSON maps each topic the recorder reported to {"type": ..., "count": ...}. The script
  * opens BAG with rosbags.rosbag2.Reader and checks its topics, their types and message counts
    against EXPECTED_JSON,
  * registers each connection's ros2msg schema (the definition with its nested ones) in an empty
    rosbags typestore and deserializes every message with it,
  * deserializes every message with rclpy.serialization.deserialize_message into the real ROS type
    (rosidl_runtime_py.utilities.get_message),
  * prints a JSON object: the counts read, the number of messages decoded both ways and the last
    rover/map_stats as rclpy read it.
It exits with 1 and says why on the first mismatch.
"""

import json
import sys

from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg
from rosidl_runtime_py.utilities import get_message


def fail(reason):
    print(f"bag_check: {reason}", file=sys.stderr)
    sys.exit(1)


def check_connections(reader, expected):
    found = {c.topic: {"type": c.msgtype, "count": c.msgcount} for c in reader.connections}
    for topic, want in expected.items():
        got = found.get(topic)
        if got is None:
            fail(f"{topic} is not in the bag; the bag has {sorted(found)}")
        if got != want:
            fail(f"{topic}: the bag has {got}, the recorder reported {want}")
    extra = sorted(set(found) - set(expected))
    if extra:
        fail(f"the bag has topics the recorder did not report: {extra}")
    return found


def typestore_of(reader):
    store = get_typestore(Stores.EMPTY)
    for connection in reader.connections:
        store.register(get_types_from_msg(connection.msgdef.data, connection.msgtype))
    return store


def main():
    bag, expected_json = sys.argv[1], sys.argv[2]
    expected = json.loads(expected_json)
    with Reader(bag) as reader:
        found = check_connections(reader, expected)
        store = typestore_of(reader)
        decoded = {topic: 0 for topic in found}
        last_stats = None
        for connection, _timestamp, raw in reader.messages():
            try:
                message = deserialize_message(bytes(raw), get_message(connection.msgtype))
            except Exception as error:
                fail(f"rclpy cannot deserialize a {connection.msgtype} on {connection.topic}: {error}")
            try:
                store.deserialize_cdr(raw, connection.msgtype)
            except Exception as error:
                fail(f"rosbags cannot deserialize a {connection.msgtype} on {connection.topic} with the bag's schema: {error}")
            decoded[connection.topic] += 1
            if connection.msgtype == "rover_msgs/msg/MapStats":
                last_stats = message
    for topic, count in decoded.items():
        if count != found[topic]["count"]:
            fail(f"{topic}: {count} messages read, the metadata says {found[topic]['count']}")
    result = {
        "counts": {topic: found[topic]["count"] for topic in found},
        "decoded": sum(decoded.values()),
        "last_map_stats": None
        if last_stats is None
        else {
            "mapped_pct": last_stats.mapped_pct,
            "fidelity_pct": last_stats.fidelity_pct,
            "navigable_cells": last_stats.navigable_cells,
        },
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
