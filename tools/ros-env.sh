# Source this file (after tools/setup-ros) to use rclpy, the Python modules of rover_msgs and tools/ros,
# and the rover package that tools/colcon-build installs:
#   source tools/ros-env.sh
_rover_repo=$(cd "$(dirname "${BASH_SOURCE[0]:-$0}")/.." && pwd)
export VIRTUAL_ENV="$_rover_repo/.venv"
export PATH="$VIRTUAL_ENV/bin:$PATH"
_rover_install="$_rover_repo/target/ros_ws/install"
# The Python of .venv (tools/setup-ros takes python3.11, or python3 without it) names the folders.
_rover_python=$(cd "$VIRTUAL_ENV/lib" 2>/dev/null && ls -d python3.* 2>/dev/null | head -n 1)
_rover_python=${_rover_python:-python3.11}
export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}"
# rover itself once tools/colcon-build has installed it (`ros2 run rover rover ...`).
for _rover_package in rover_msgs $(cd "$_rover_repo/tools/ros" && ls -d -- */ | tr -d /) rover; do
  _rover_prefix="$_rover_install/$_rover_package"
  export AMENT_PREFIX_PATH="$_rover_prefix:$AMENT_PREFIX_PATH"
  export PYTHONPATH="$_rover_prefix/lib/$_rover_python/site-packages${PYTHONPATH:+:$PYTHONPATH}"
  export LD_LIBRARY_PATH="$_rover_prefix/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
done
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
export ROS_DISTRO=kilted
unset _rover_repo _rover_install _rover_python _rover_package _rover_prefix
