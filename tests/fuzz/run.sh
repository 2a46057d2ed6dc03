#!/usr/bin/env bash
# Longer, coverage-guided runs of the fuzz targets (cargo-fuzz + libFuzzer), seeded from
# tests/corpus/. The test command replays that corpus with bounded random mutations
# (fuzz/tests/corpus.rs); this script is for hours, not a minute.
#
# Usage: tests/fuzz/run.sh [SECONDS_PER_TARGET] [TARGET...]   (default 300 s, every target)
# Needs cargo-fuzz (`cargo install cargo-fuzz`) and a nightly rustc (or RUSTC_BOOTSTRAP=1,
# which this script sets when no nightly toolchain is installed).
# Crashes, hangs (> 10 s) and out-of-memory inputs land in target/fuzz-findings/<target>/;
# once fixed, copy each (minimised with `cargo fuzz tmin`) into tests/corpus/<target>/.
# The growing working corpus stays in target/fuzz-corpus/<target>/.
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-300}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(cdr bag dataset urdf trainer_request)
toolchain=()
if rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
  toolchain=(+nightly)
else
  export RUSTC_BOOTSTRAP=1
fi
for t in "${targets[@]}"; do
  mkdir -p "target/fuzz-corpus/$t" "target/fuzz-findings/$t"
  echo "==> $t for ${seconds}s"
  cargo "${toolchain[@]}" fuzz run --fuzz-dir fuzz --features libfuzzer "$t" \
    "target/fuzz-corpus/$t" "tests/corpus/$t" -- \
    -max_total_time="$seconds" -timeout=10 -rss_limit_mb=4096 -malloc_limit_mb=2048 \
    -artifact_prefix="target/fuzz-findings/$t/"
done
