"""Drive the rover with navigate_to_pose as a Nav2 user's script does (send a goal, poll until it
is complete, read its feedback, cancel), and write what happened as JSON for tests/commanding.rs.

Goals are drawn with a seeded generator over the world's reachable floor: drivable cells (as
`rover sim --export-drivable` writes them: white, row = y, column = x) with 2 m of drivable cells
all around, reached from the rover's start without leaving them. Then a goal preempted by the next, a goal off the map, a goal inside a wall next to
where the rover stands, and a goal canceled while the rover drives to it.
"""

import argparse
import json
import math
import random
import time
from collections import deque

import numpy as np
import rclpy
from action_msgs.msg import GoalStatus
from nav2_msgs.action import NavigateToPose
from PIL import Image
from rclpy.action import ActionClient
from rover_msgs.action import SampleReturn
from rover_msgs.msg import Telemetry

GOAL_TIMEOUT_S = 240.0
CLEARANCE_CELLS = 2
STATUS_NAMES = {GoalStatus.STATUS_SUCCEEDED: 'SUCCEEDED', GoalStatus.STATUS_ABORTED: 'ABORTED',
                GoalStatus.STATUS_CANCELED: 'CANCELED'}


class Navigator:
    """The goToPose / isTaskComplete / getFeedback / cancelTask pattern of nav2_simple_commander."""

    def __init__(self, node):
        self.node = node
        self.client = ActionClient(node, NavigateToPose, 'navigate_to_pose')
        self.goal_handle = None
        self.result_future = None
        self.feedback = None
        self.feedbacks = []
        self.status = None

    def go_to_pose(self, x, y):
        goal = NavigateToPose.Goal()
        goal.pose.header.frame_id = 'map'
        goal.pose.pose.position.x, goal.pose.pose.position.y = float(x), float(y)
        goal.pose.pose.orientation.w = 1.0
        self.feedback, self.status = None, None
        sent = self.client.send_goal_async(goal, feedback_callback=self._on_feedback)
        rclpy.spin_until_future_complete(self.node, sent, timeout_sec=30.0)
        self.goal_handle = sent.result()
        if self.goal_handle is None or not self.goal_handle.accepted:
            return False
        self.result_future = self.goal_handle.get_result_async()
        return True

    def _on_feedback(self, message):
        self.feedback = message.feedback
        self.feedbacks.append(message.feedback.distance_remaining)

    def is_task_complete(self):
        rclpy.spin_until_future_complete(self.node, self.result_future, timeout_sec=0.1)
        if not self.result_future.done():
            return False
        self.status = self.result_future.result().status
        return True

    def result(self):
        return self.result_future.result().result

    def cancel_task(self):
        cancel = self.goal_handle.cancel_goal_async()
        rclpy.spin_until_future_complete(self.node, cancel, timeout_sec=10.0)
        return cancel.result()


def load_floor(path):
    return np.array(Image.open(path).convert('L')) > 0


def clear_floor(floor):
    """Floor cells with CLEARANCE_CELLS of floor all around."""
    clear = floor.copy()
    for dy in range(-CLEARANCE_CELLS, CLEARANCE_CELLS + 1):
        for dx in range(-CLEARANCE_CELLS, CLEARANCE_CELLS + 1):
            clear &= np.roll(np.roll(floor, dy, axis=0), dx, axis=1)
    return clear


def reachable(floor, start):
    """Floor cells (x, y) reached from start through 4-connected floor."""
    seen = {start}
    queue = deque([start])
    height, width = floor.shape
    while queue:
        x, y = queue.popleft()
        for nx, ny in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if 0 <= nx < width and 0 <= ny < height and floor[ny, nx] and (nx, ny) not in seen:
                seen.add((nx, ny))
                queue.append((nx, ny))
    return seen


class Probe:
    def __init__(self, node):
        self.node = node
        self.telemetry = None
        node.create_subscription(Telemetry, 'rover/telemetry', self._on_telemetry, 10)
        self.navigator = Navigator(node)

    def _on_telemetry(self, message):
        self.telemetry = message

    def spin_until(self, condition, timeout_s):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            rclpy.spin_once(self.node, timeout_sec=0.05)
            if condition():
                return True
        return False

    def position(self):
        return self.telemetry.x_m, self.telemetry.y_m

    def drive_to(self, x, y, timeout_s=GOAL_TIMEOUT_S):
        """Sends a goal and waits for its end: what a test checks about it."""
        nav = self.navigator
        nav.feedbacks = []
        started = time.monotonic()
        if not nav.go_to_pose(x, y):
            return {'goal': [x, y], 'status': 'REJECTED'}
        while not nav.is_task_complete():
            if time.monotonic() - started > timeout_s:
                nav.cancel_task()
                return {'goal': [x, y], 'status': 'TIMEOUT', 'feedback': nav.feedbacks}
        rclpy.spin_once(self.node, timeout_sec=0.2)
        result = nav.result()
        px, py = self.position()
        return {'goal': [x, y], 'status': STATUS_NAMES.get(nav.status, str(nav.status)),
                'error_code': result.error_code, 'error_msg': result.error_msg,
                'final_distance_m': math.hypot(px - x, py - y), 'feedback': nav.feedbacks,
                'wall_s': time.monotonic() - started}

    def cancel_mid_way(self, x, y):
        """Sends a goal, cancels it once the rover drives, and counts the frames until it brakes and
        until it stops."""
        nav = self.navigator
        nav.feedbacks = []
        if not nav.go_to_pose(x, y):
            return {'status': 'REJECTED'}
        driving = self.spin_until(lambda: self.telemetry.speed_mps > 1.0, 120.0)
        frame = self.telemetry.frame
        cancel = nav.cancel_task()
        braked = self.spin_until(lambda: self.telemetry.brake > 0.0, 30.0)
        brake_frame = self.telemetry.frame
        stopped = self.spin_until(lambda: abs(self.telemetry.speed_mps) < 0.2, 30.0)
        stop_frame = self.telemetry.frame
        done = self.spin_until(nav.is_task_complete, 30.0)
        return {'driving': driving, 'cancel_goals': len(cancel.goals_canceling) if cancel else 0,
                'frames_to_brake': brake_frame - frame, 'brake': braked,
                'stopped': stopped, 'frames_to_stop': stop_frame - frame,
                'status': STATUS_NAMES.get(nav.status, str(nav.status)) if done else 'PENDING'}


    def preempt(self, first, second):
        """Sends `first`, then `second` while the rover drives to the first: the first ends
        aborted, the second is driven to."""
        earlier = Navigator(self.node)
        if not earlier.go_to_pose(*first):
            return {'status': 'REJECTED'}
        self.spin_until(lambda: len(earlier.feedbacks) >= 2, 60.0)
        report = {'second': self.drive_to(*second)}
        done = self.spin_until(earlier.is_task_complete, 30.0)
        report['first'] = STATUS_NAMES.get(earlier.status, 'PENDING') if done else 'PENDING'
        report['first_message'] = earlier.result().error_msg if done else ''
        return report

    def mission_then_cancel(self):
        """Starts the mission with sample_return, reads its feedback, cancels it: the rover holds."""
        client = ActionClient(self.node, SampleReturn, 'sample_return')
        feedbacks = []
        sent = client.send_goal_async(SampleReturn.Goal(), feedback_callback=lambda m: feedbacks.append(m.feedback))
        rclpy.spin_until_future_complete(self.node, sent, timeout_sec=30.0)
        handle = sent.result()
        if handle is None or not handle.accepted:
            return {'status': 'REJECTED'}
        result = handle.get_result_async()
        self.spin_until(lambda: len(feedbacks) >= 3, 60.0)
        cancel = handle.cancel_goal_async()
        rclpy.spin_until_future_complete(self.node, cancel, timeout_sec=10.0)
        stopped = self.spin_until(lambda: abs(self.telemetry.speed_mps) < 0.2 and self.telemetry.brake > 0.0, 30.0)
        done = self.spin_until(result.done, 30.0)
        return {'feedback_modes': [f.mode for f in feedbacks], 'stopped': stopped,
                'status': STATUS_NAMES.get(result.result().status, 'PENDING') if done else 'PENDING',
                'message': result.result().result.message if done else ''}


def draw_goals(floor, start, count, seed):
    clear = clear_floor(floor)
    cells = sorted(cell for cell in reachable(floor, start) if clear[cell[1], cell[0]])
    rng = random.Random(seed)
    goals, at = [], start
    for _ in range(count):
        near = [c for c in cells if 8.0 <= math.dist(c, at) <= 30.0]
        cell = rng.choice(near or cells)
        goals.append((cell[0] + 0.5, cell[1] + 0.5))
        at = cell
    return goals, cells


def wall_goal(floor, at):
    """A cell inside a wall (no floor within 1 cell) with floor within 3 cells, nearest to `at`."""
    height, width = floor.shape
    best = None
    for y in range(3, height - 3):
        for x in range(3, width - 3):
            if floor[y - 1:y + 2, x - 1:x + 2].any() or not floor[y - 3:y + 4, x - 3:x + 4].any():
                continue
            distance = math.dist((x, y), at)
            if best is None or distance < best[0]:
                best = (distance, (x + 0.5, y + 0.5))
    return best[1]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument('--map', required=True)
    parser.add_argument('--seed', type=int, default=0)
    parser.add_argument('--goals', type=int, default=5)
    parser.add_argument('--out', required=True)
    args = parser.parse_args()

    rclpy.init()
    node = rclpy.create_node('goal_probe')
    probe = Probe(node)
    report = {}
    if not probe.navigator.client.wait_for_server(timeout_sec=60.0):
        report['error'] = 'no navigate_to_pose server'
    elif not probe.spin_until(lambda: probe.telemetry is not None, 60.0):
        report['error'] = 'no telemetry'
    else:
        floor = load_floor(args.map)
        start = tuple(int(v) for v in probe.position())
        goals, cells = draw_goals(floor, start, args.goals, args.seed)
        report['start'] = list(probe.position())
        report['goals'] = [probe.drive_to(x, y) for x, y in goals]
        rng = random.Random(args.seed + 2)
        at = probe.position()
        far = [c for c in cells if 20.0 <= math.dist(c, at) <= 40.0] or cells
        near = [c for c in cells if 6.0 <= math.dist(c, at) <= 12.0] or cells
        first, second = rng.choice(far), rng.choice(near)
        report['preempt'] = probe.preempt((first[0] + 0.5, first[1] + 0.5), (second[0] + 0.5, second[1] + 0.5))
        report['off_map'] = probe.drive_to(250.0, 100.0, timeout_s=30.0)
        report['in_wall'] = probe.drive_to(*wall_goal(floor, probe.position()), timeout_s=120.0)
        at = probe.position()
        far = [c for c in cells if 20.0 <= math.dist(c, at) <= 40.0]
        target = random.Random(args.seed + 1).choice(far or cells)
        report['cancel'] = probe.cancel_mid_way(target[0] + 0.5, target[1] + 0.5)
        report['mission'] = probe.mission_then_cancel()
    with open(args.out, 'w') as out:
        json.dump(report, out, indent=1)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
