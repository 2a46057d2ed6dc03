#!/usr/bin/env bash
# The project's one test command (see README): installs the system packages it lacks
# (tests/system_packages.sh), builds everything, prepares the Python venv of independent
# oracles (cached under target/pyvenv) and the ROS 2 Jazzy and Kilted wheels with our
# colcon-built interfaces (target/ros), then runs the Rust tests, the patched crates' unit
# tests and the Python interop tests (real rclpy among them). Everything that may start a
# DDS participant runs inside a private loopback-only network namespace (tests/netns-run),
# so no traffic leaves the host.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
VENV=${CAUSAL_ARM_VENV:-$ROOT/target/pyvenv}
REQ=$ROOT/tests/python/requirements.txt
PYTHON=${PYTHON:-python3}

step() { printf '\n==> %s\n' "$*"; }

step "system packages"
bash "$ROOT/tests/system_packages.sh"

step "patched crates: patches/*/ are exactly crates.io + patches/*.series (patches/rebuild.sh)"
bash "$ROOT/patches/rebuild.sh"

step "Python venv with pinned oracles ($VENV)"
stamp=$VENV/.requirements.sha256
want=$(sha256sum "$REQ" | cut -d' ' -f1)
if [ ! -x "$VENV/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  "$PYTHON" -m venv "$VENV"
  "$VENV/bin/python" -m pip install --quiet --upgrade pip
  "$VENV/bin/python" -m pip install --quiet -r "$REQ"
  echo "$want" > "$stamp"
else
  echo "up to date"
fi

for distro in jazzy kilted; do
  step "ROS 2 $distro: rclpy wheels and colcon-built interfaces (target/ros/$distro)"
  PYTHON=$PYTHON bash "$ROOT/tests/ros2/setup.sh" "$distro"
done

step "cargo build (workspace binaries)"
cargo build --workspace --bins --locked

step "cargo test --workspace (inside a private network namespace)"
tests/netns-run cargo test --workspace --locked

step "unit tests of the patched crates (patches/)"
bash "$ROOT/tests/patched_crates.sh"

step "Python interop tests (inside a private network namespace)"
tests/netns-run "$VENV/bin/python" -m pytest -q tests/python "$@"

step "all tests passed"
