#!/usr/bin/env bash
# The unit tests of the crates we patch (patches/): upstream's own suites plus the tests our
# diffs add. Cargo cannot test a [patch] path dependency that has dev-dependencies from
# inside this workspace, so they run in a copy made into a workspace of their own. The
# dependencies are fetched first; the tests, which open DDS sockets, then run offline inside
# the private network namespace (tests/netns-run).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
DIR=$ROOT/target/patched-crates
mkdir -p "$DIR"
rm -rf "$DIR/rustdds" "$DIR/ros2-client"
cp -r patches/rustdds patches/ros2-client "$DIR/"
# Our lock pins every dependency they share with us; only their dev-dependencies resolve anew.
cp Cargo.lock "$DIR/"
cat > "$DIR/Cargo.toml" <<'TOML'
[workspace]
members = ["rustdds", "ros2-client"]
resolver = "2"

[patch.crates-io]
rustdds = { path = "rustdds" }
TOML
cd "$DIR"
cargo fetch --quiet
export CARGO_TARGET_DIR=$DIR/target
"$ROOT/tests/netns-run" cargo test --offline --quiet -p rustdds --lib --features security
"$ROOT/tests/netns-run" cargo test --offline --quiet -p ros2-client --lib
