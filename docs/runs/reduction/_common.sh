# Shared by the run*.sh scripts of this directory (source it): strict mode, the repository
# root as working directory, the binary, the log directory, and the two helpers every run
# uses. Each step logs into this directory; models go to models/ (not committed; their
# metrics.json are copied here).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../../.."
B=${CAUSAL_ARM:-target/release/causal-arm}
LOG=docs/runs/reduction
step() { echo "==> $(date -u +%H:%M:%S) $*"; }
train() { # out, log name, args...
  local out=$1 name=$2; shift 2
  step "train $name"
  $B train "$@" --out "$out" 2> "$LOG/$name.err" | tee "$LOG/$name.txt"
  cp "$out/metrics.json" "$LOG/$name.metrics.json"
}
# The paper-profile bags the runs read (the truth bags of docs/truth), made if missing.
paper_bags() {
  [ -f bags/paper_exp1/metadata.yaml ] || $B generate exp1 --profile paper --seed 1 --out bags/paper_exp1
  [ -f bags/paper_exp2_mws/metadata.yaml ] || $B generate exp2 --profile paper --seed 1 --out bags/paper_exp2_mws
}
