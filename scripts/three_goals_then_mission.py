"""Three navigate_to_pose goals, then the mission: beside a graph run with decision:start_mission:=false."""
import sys
import rclpy
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionClient
from std_srvs.srv import Trigger

GOALS = [tuple(map(float, g.split(','))) for g in sys.argv[1:]] or [(106.5, 90.5), (111.5, 98.5), (100.5, 86.5)]
rclpy.init()
node = rclpy.create_node('three_goals')
navigate = ActionClient(node, NavigateToPose, 'navigate_to_pose')
navigate.wait_for_server()
for x, y in GOALS:
    goal = NavigateToPose.Goal()
    goal.pose.header.frame_id, goal.pose.pose.orientation.w = 'map', 1.0
    goal.pose.pose.position.x, goal.pose.pose.position.y = x, y
    sent = navigate.send_goal_async(goal, feedback_callback=lambda f: print(f'{f.feedback.distance_remaining:.1f} m left'))
    rclpy.spin_until_future_complete(node, sent)
    done = sent.result().get_result_async()
    rclpy.spin_until_future_complete(node, done)
    print(f'goal ({x}, {y}): status {done.result().status}, error {done.result().result.error_code}')
start = node.create_client(Trigger, 'decision/start_mission')
start.wait_for_service()
answer = start.call_async(Trigger.Request())
rclpy.spin_until_future_complete(node, answer)
print('start_mission:', answer.result().message)
