#!/usr/bin/env bash
# The drift pool's rooms replayed by the builds of earlier commits (issue 54's "at most the
# better of b3bc40e's and cd32c3f's figures"; docs/results/ANALYSIS.md, "The driving regression's
# target on the pool"). Each COMMIT is checked out in a git worktree under WORK, its
# omnipose-replay built (Release), and every room of POOL (the output directory of
# `tools/drift_pool.sh POOL`, which keeps each room's dataset and the present build's
# default.txt) replayed with the defaults and its own FFTW wisdom file; the present build's
# omnipose-eval --drift scores each. Prints a row per room: end-point [deg] / per-pair eps
# [mrad] for each commit, then for the present build.
# Usage: docs/results/experiments/drift_pool_commits.sh POOL WORK COMMIT...
#   e.g. tools/drift_pool.sh /tmp/pool && \
#        docs/results/experiments/drift_pool_commits.sh /tmp/pool /tmp/commits b3bc40e cd32c3f
# (about 1 min to build each commit's replay and 20 s a room to replay it, 2 cores).
set -euo pipefail
if [ $# -lt 3 ]; then
  echo "usage: drift_pool_commits.sh POOL WORK COMMIT..." >&2
  exit 2
fi
root=$(cd "$(dirname "$0")/../../.." && pwd)
pool=$(realpath "$1")
work=$(realpath -m "$2")
shift 2
commits=("$@")
eval_bin=$root/build/bin/omnipose-eval
[ -x "$eval_bin" ] || { echo "drift_pool_commits: $eval_bin missing (tools/build.sh)" >&2; exit 1; }
mkdir -p "$work"
for commit in "${commits[@]}"; do
  tree=$work/$commit
  [ -d "$tree" ] || git -C "$root" worktree add -f --detach "$tree" "$commit" > /dev/null
  cmake -S "$tree" -B "$tree/build" -G Ninja -DCMAKE_BUILD_TYPE=Release > "$tree/configure.log"
  cmake --build "$tree/build" -j"$(nproc)" --target omnipose-replay > "$tree/build.log"
  printf 'pipeline:\n  fftw_wisdom: "%s/replay.wisdom"\n' "$tree" > "$tree/replay.yaml"
done
score() {  # score TXT: "end-point / eps" from omnipose-eval --drift's text
  awk '/end-point rotation error/ { e = $4 } /per-pair eps RMSE/ { p = $4 }
       END { printf "%.3f / %.3f", e, p }' "$1"
}
header="| room |"
for commit in "${commits[@]}"; do header+=" $commit |"; done
echo "$header present build |"
for dir in "$pool"/*/; do
  room=$(basename "$dir")
  [ -d "$dir/dataset" ] && [ -f "$dir/default.txt" ] || continue
  row="| $room |"
  for commit in "${commits[@]}"; do
    tree=$work/$commit
    "$tree/build/bin/omnipose-replay" "$dir/dataset" --config "$tree/replay.yaml" --quiet \
      --out "$dir/$commit.tum" > /dev/null 2> "$dir/$commit.log"
    "$eval_bin" --drift "$dir/dataset/groundtruth.tum" "$dir/$commit.tum" > "$dir/$commit.txt"
    row+=" $(score "$dir/$commit.txt") |"
  done
  echo "$row $(score "$dir/default.txt") |"
done
