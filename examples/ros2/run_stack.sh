#!/usr/bin/env bash
# NEEDS ROS 2 (a sourced /opt/ros/<distro>/setup.bash) and your stack's package. Not run by the tests: the machine
# riverbench is developed on has no ROS 2.
#
# A riverbench command component that runs a ROS 2 launch on the bench's recording: it starts the launch on
# simulated time, records the stack's nav_msgs/Odometry topic, plays the bag with --clock, then converts the recorded
# topic to TUM (header stamps, UNIX time) in OUT. In a scenario (docs/guide.md, "Bring your own stack"):
#
#   [[estimators]]
#   id = "my_stack"
#   kind = "command"
#   command = "examples/ros2/run_stack.sh {recording} {out} my_pkg localization.launch.py /odometry/filtered"
#   recording = "rosbag2"
#   output = "out/odometry.tum"
#   anchor = "map"            # poses in the map frame; "first" or "se3" for odometry in a frame of its own
#   timeout_s = 900
#
# The bench runs it in its own process group and ends the group (SIGTERM, then SIGKILL) on a timeout or Ctrl-C; the
# trap below passes that on to the launch and the recorder.
set -euo pipefail
if [ $# -ne 5 ]; then
    echo "usage: run_stack.sh BAG OUT PACKAGE LAUNCH_FILE ODOMETRY_TOPIC" >&2
    exit 2
fi
bag=$1 out=$2 package=$3 launch=$4 topic=$5
here=$(cd "$(dirname "$0")" && pwd)
command -v ros2 >/dev/null || { echo "ros2 not found: source /opt/ros/<distro>/setup.bash first" >&2; exit 2; }

pids=()
cleanup() { for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done; wait || true; }
trap cleanup EXIT

ros2 launch "$package" "$launch" use_sim_time:=true &
pids+=($!)
ros2 bag record --use-sim-time -o "$out/odometry_bag" "$topic" &
pids+=($!)
sleep 5                                   # let the stack and the recorder discover each other
ros2 bag play "$bag" --clock --rate 1.0   # /clock from the bag: the stack runs on the recording's time
sleep 2                                   # the last messages reach the recorder
cleanup
trap - EXIT
"${RIVERBENCH_PYTHON:-python3}" "$here/odometry_to_tum.py" "$out/odometry_bag" "$topic" "$out/odometry.tum"
