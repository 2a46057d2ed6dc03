#!/usr/bin/env bash
# Real ROS 2 for the interop tests, as a user without apt gets it: a venv with DISTRO's rclpy
# and rmw_fastrtps_cpp wheels (pinned in tests/ros2/DISTRO.txt) and a colcon workspace that
# builds msgs/ (causal_arm_msgs) and tf2_msgs against them. Cached under target/ros/DISTRO
# and rebuilt only when the pins, this script or an interface file changes.
#
#   bash tests/ros2/setup.sh jazzy|kilted     # then: source target/ros/DISTRO/env.sh
set -euo pipefail
DISTRO=${1:?usage: setup.sh jazzy|kilted}
cd "$(dirname "$0")/../.."
ROOT=$PWD
PINS=$ROOT/tests/ros2/$DISTRO.txt
[ -f "$PINS" ] || { echo "setup.sh: no pins for '$DISTRO' ($PINS)" >&2; exit 2; }
DIR=$ROOT/target/ros/$DISTRO
VENV=$DIR/venv
PYTHON=${PYTHON:-python3}

inputs() {
  cat "$PINS" "$0"
  find msgs/msg msgs/srv msgs/CMakeLists.txt msgs/package.xml tests/ros2/tf2_msgs -type f -o -type l \
    | sort | xargs cat
}
want=$(inputs | sha256sum | cut -d' ' -f1)
if [ "$(cat "$DIR/.inputs.sha256" 2>/dev/null)" = "$want" ]; then
  echo "ROS 2 $DISTRO: up to date ($DIR)"
  exit 0
fi
# The wheels are built for CPython 3.11 only (cp311-manylinux_2_28_x86_64).
version=$("$PYTHON" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
if [ "$version" != "3.11" ]; then
  echo "setup.sh: the ROS 2 $DISTRO wheels need Python 3.11, $PYTHON is $version (set PYTHON=python3.11)" >&2
  exit 1
fi
rm -rf "$DIR"
mkdir -p "$DIR"

echo "ROS 2 $DISTRO: wheels ($VENV)"
"$PYTHON" -m venv "$VENV"
"$VENV/bin/python" -m pip install --quiet --upgrade pip
"$VENV/bin/python" -m pip install --quiet -r "$PINS"

# The wheels' CMake exports name the Python and numpy include directories of the machine
# that built them (/opt/python/cp311-cp311/...): CMake refuses an imported target whose
# include directory does not exist. Point them at this venv's.
py_include=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
np_include=$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')
[ -f "$py_include/Python.h" ] || { echo "setup.sh: no Python.h in $py_include (install the Python headers)" >&2; exit 1; }
grep -rlE '/opt/python/cp311-cp311/(include|lib)' "$VENV/share" --include='*.cmake' \
  | xargs -r sed -i -e "s#/opt/python/cp311-cp311/include/python3.11#$py_include#g" \
                    -e "s#/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include#$np_include#g"

echo "ROS 2 $DISTRO: colcon build of causal_arm_msgs and tf2_msgs"
(
  # shellcheck disable=SC1091
  source "$VENV/bin/activate"
  export AMENT_PREFIX_PATH=$VENV CMAKE_PREFIX_PATH=$VENV
  colcon --log-base "$DIR/log" build --base-paths msgs tests/ros2/tf2_msgs \
    --build-base "$DIR/build" --install-base "$DIR/install" \
    --event-handlers console_direct- console_cohesion- --cmake-args -DBUILD_TESTING=OFF \
    > "$DIR/colcon.log" 2>&1 || { tail -40 "$DIR/colcon.log" >&2; echo "setup.sh: colcon build failed (log: $DIR/colcon.log)" >&2; exit 1; }
)

# What a user's shell would have after sourcing the venv and the workspace.
cat > "$DIR/env.sh" <<EOF
# ROS 2 $DISTRO wheels and the colcon-built interfaces (made by tests/ros2/setup.sh).
source "$VENV/bin/activate"
export AMENT_PREFIX_PATH="$VENV"
source "$DIR/install/setup.sh"
export RMW_IMPLEMENTATION=rmw_fastrtps_cpp
EOF
echo "$want" > "$DIR/.inputs.sha256"
echo "ROS 2 $DISTRO: ready (source $DIR/env.sh)"
