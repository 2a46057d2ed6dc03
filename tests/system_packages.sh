#!/usr/bin/env bash
# Installs the Debian/Ubuntu packages the tests need and a fresh machine lacks (nothing
# when all are present): the network namespace tools, the venv module, a C/C++ toolchain
# and OpenSSL for DDS Security. Called by tests/run_all.sh, so the README's test command sets
# itself up. (rmw_fastrtps comes with the ROS 2 wheels: tests/ros2/setup.sh.)
set -euo pipefail
SUDO=""
if [ "$(id -u)" != 0 ]; then SUDO="sudo"; fi
need=()
command -v unshare >/dev/null || need+=(util-linux)
command -v ip >/dev/null || need+=(iproute2)
command -v python3 >/dev/null || need+=(python3)
python3 -c 'import venv, ensurepip' 2>/dev/null || need+=(python3-venv)
command -v cc >/dev/null || need+=(build-essential)
command -v pkg-config >/dev/null || need+=(pkg-config)
# DDS Security (rustdds' `security` feature) links OpenSSL; `openssl` verifies keystores in tests.
pkg-config --exists openssl 2>/dev/null || need+=(libssl-dev)
command -v openssl >/dev/null || need+=(openssl)
if [ "${#need[@]}" -gt 0 ]; then
  echo "installing: ${need[*]}"
  $SUDO apt-get update -q
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -q "${need[@]}"
else
  echo "all present"
fi
