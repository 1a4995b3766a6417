"""Launch the rover graph: each node its own process running the `rover` executable.

    ros2 launch rover rover.launch.py [ARGUMENT:=VALUE]...     (installed by colcon)
    ros2 launch launch_scripts/rover.launch.py [namespace:=/rover1] [params_file:=FILE]
        [rover:=PATH] [port:=4567] [sim:=true] [seed:=0] [log_level:=debug]
        [respawn:=false] [state_dir:=DIR] [use_sim_time:=true]
        [groups:='bridge,perception mapping,decision,pickup'] [cmd_vel:=/teleop/cmd_vel]

Every node that `rover nodes` lists runs as a launch_ros Node: `rover NODE` named NODE in
NAMESPACE with the parameter file PARAMS and use_sim_time (the bridge also port, mapping and
decision state_dir) [--log-level LEVEL] and its DDS Security enclave /rover/NODE (used when
ROS_SECURITY_ENABLE=true). The bridge takes teleoperation from the topic cmd_vel (remapped). With use_sim_time:=true every node
stamps with the simulated time the bridge publishes on /clock. With sim:=true the headless simulator (`rover sim --seed SEED
--port PORT`) drives the graph; without it the bridge waits for the Unity simulator. The DDS
domain is the environment's ROS_DOMAIN_ID, the log filter RUST_LOG unless log_level is given.
With groups (space-separated, each a comma-separated list of nodes) each group runs in one
process, `rover container NODE...`, and every other node alone.
A process that dies is started again after RESPAWN_DELAY_S (respawn:=false: it stays dead), and the
mapping and decision nodes carry on from their snapshots in state_dir (default: a new temporary
folder per launch).
`rover` is not in an ament package index unless the repository was built with colcon, so the
Node actions start it by path (the rover argument).
"""

import os
import shutil
import subprocess
import tempfile

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

HERE = os.path.dirname(os.path.abspath(__file__))
RESPAWN_DELAY_S = 0.5


def default_rover():
    """The `rover` executable: the newest cargo build of this repository, else the one a colcon
    build installed (lib/rover/rover), else the one on PATH."""
    builds = [os.path.normpath(os.path.join(HERE, '..', 'target', profile, 'rover')) for profile in ('release', 'debug')]
    builds = [path for path in builds if os.access(path, os.X_OK)]
    if builds:
        return max(builds, key=os.path.getmtime)
    installed = colcon_installed_rover()
    if installed:
        return installed
    return shutil.which('rover') or 'rover'


def colcon_installed_rover():
    """lib/rover/rover in the ament prefix of the `rover` package, if a colcon build installed it."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    except ImportError:
        return None
    try:
        candidate = os.path.join(get_package_prefix('rover'), 'lib', 'rover', 'rover')
    except PackageNotFoundError:
        return None
    return candidate if os.access(candidate, os.X_OK) else None


def process_groups(rover, groups):
    """The graph's processes, each a list of nodes, as `rover nodes --group GROUP...` lists them:
    each of the space-separated `groups` together, every other node alone, in start order."""
    command = [rover, 'nodes'] + ['--group=' + group for group in groups.split()]
    listed = subprocess.run(command, stdin=subprocess.DEVNULL, capture_output=True, text=True)
    if listed.returncode != 0:
        raise RuntimeError('groups:=%r: %s' % (groups, listed.stderr.strip().splitlines()[0]))
    return [line.split() for line in listed.stdout.splitlines() if line.strip()]


def arguments():
    """The launch arguments with their defaults."""
    on_off = ['true', 'false']
    declared = [
        # name, default, description, allowed values (None: any)
        ('namespace', '/', 'ROS namespace of every node, e.g. /rover1', None),
        ('params_file', os.path.join(HERE, 'rover_params.yaml'), 'parameter YAML file given to every node', None),
        ('rover', default_rover(), 'path of the rover executable', None),
        ('port', '4567', "TCP port of the bridge's Socket.IO server", None),
        ('sim', 'false', 'also start the headless simulator (rover sim)', on_off),
        ('seed', '0', "seed of the headless simulator's world", None),
        ('log_level', '', 'log level of every node (default: RUST_LOG, else info)', None),
        ('respawn', 'true', 'start a node that dies again', on_off),
        ('autostart', 'true', 'nodes configure and activate themselves; false: they start unconfigured '
         'and rover lifecycle-manager brings them up in order', on_off),
        ('state_dir', '', 'folder of the mapping and decision snapshots (default: a new temporary one)', None),
        ('use_sim_time', 'false', "stamp every node's messages with the simulated time of /clock", on_off),
        ('cmd_vel', 'cmd_vel', "the topic the bridge takes teleoperation's Twist commands from", None),
        ('groups', '', 'nodes that share a process, e.g. "bridge,perception mapping,decision,pickup" '
         '(default: each node alone)', None),
    ]
    return [DeclareLaunchArgument(name, default_value=default, description=description,
                                  **({'choices': choices} if choices else {}))
            for name, default, description, choices in declared]


def own_parameters(name, value, state_dir):
    """The parameters the launcher gives node `name` beside the parameter file."""
    own = {'use_sim_time': value('use_sim_time') == 'true'}
    if value('autostart') == 'false':
        own['autostart'] = False
    if name == 'bridge':
        own['port'] = int(value('port'))
    if name in ('mapping', 'decision'):
        own['state_dir'] = state_dir
    return own


def process_action(group, value, state_dir, respawn):
    """The process of the nodes `group` as a launch_ros Node: `rover NODE`, named by launch_ros,
    for one node; `rover container NODE...` for several, each node's own parameters aimed at it
    (-p NODE:NAME:=VALUE). Namespaced and given the parameter file by launch_ros; `value` reads
    a launch argument."""
    log_level = ['--log-level', value('log_level')] if value('log_level') else []
    common = dict(executable=value('rover'), namespace=value('namespace'), output='screen', sigterm_timeout='5',
                  sigkill_timeout='5', respawn=respawn, respawn_delay=RESPAWN_DELAY_S)
    if len(group) == 1:
        name = group[0]
        return Node(arguments=[name], exec_name=name, name=name, ros_arguments=log_level + enclave(name),
                    parameters=[value('params_file'), own_parameters(name, value, state_dir)],
                    remappings=own_remappings(name, value), **common)
    aimed = [arg for name in group for key, own in own_parameters(name, value, state_dir).items()
             for arg in ('-p', '%s:%s:=%s' % (name, key, yaml_value(own)))]
    aimed += [arg for name in group for source, target in own_remappings(name, value)
              for arg in ('-r', '%s:%s:=%s' % (name, source, target))]
    return Node(arguments=['container'] + group, exec_name='+'.join(group), parameters=[value('params_file')],
                ros_arguments=aimed + log_level, **common)


def own_remappings(name, value):
    """The topic remappings the launcher gives node `name`: the bridge's cmd_vel."""
    return [('cmd_vel', value('cmd_vel'))] if name == 'bridge' else []


def enclave(name):
    """The ROS arguments that give the process `name` its own DDS Security enclave (used when
    ROS_SECURITY_ENABLE=true; tools/keystore makes them)."""
    return ['--enclave', '/rover/' + name]


def yaml_value(value):
    """A parameter value as -p NAME:=VALUE reads it."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def simulator_command(value):
    """The command line of the headless simulator, connecting to the bridge's port."""
    return [value('rover'), 'sim', '--seed', value('seed'), '--port', value('port')]


def processes(context):
    """One process per node or group of nodes, plus the lifecycle manager with autostart:=false
    and the simulator with sim:=true."""
    def value(name):
        return LaunchConfiguration(name).perform(context)

    state_dir = value('state_dir') or tempfile.mkdtemp(prefix='rover-state-')
    respawn = value('respawn') == 'true'
    groups = process_groups(value('rover'), value('groups'))
    actions = [process_action(group, value, state_dir, respawn) for group in groups]
    if value('autostart') == 'false':
        actions.append(Node(executable=value('rover'), arguments=['lifecycle-manager'], exec_name='lifecycle_manager',
                            ros_arguments=enclave('lifecycle_manager'),
                            namespace=value('namespace'), output='screen', sigterm_timeout='5',
                            sigkill_timeout='5', respawn=respawn, respawn_delay=RESPAWN_DELAY_S))
    if value('sim') == 'true':
        actions.append(ExecuteProcess(cmd=simulator_command(value), name='sim', output='screen',
                                      sigterm_timeout='5', sigkill_timeout='5'))
    return actions


def generate_launch_description():
    """The launch description that `ros2 launch` and `launch.LaunchService` load."""
    return LaunchDescription(arguments() + [OpaqueFunction(function=processes)])
