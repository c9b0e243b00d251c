#!/usr/bin/env bash
# Replays the renders a benchmark kept with an experiment's environment variables set
# (the variables of a patch in this directory), and prints one line per render: the figure
# docs/results/ANALYSIS.md compares. Run it once without variables (the build as kept) and
# once with them, on the same binaries.
#
# Usage: replay_with_env.sh KIND DIR [VAR=VALUE ...] [pipeline.KEY=VALUE ...]
#   VAR=VALUE          an environment variable of the replays (an experiment's)
#   pipeline.KEY=VALUE a key of daemon.yaml's `pipeline:` section added to the benchmark's
#                      replay configuration (a setting compared with the defaults)
#   KIND people    DIR from `tools/people_benchmark.sh DIR`: SCENE/SITUATION and the ratio
#                  of its eps (mrad, the RMS of omnipose-eval's per-pair eps) to its twin's
#                  (twin_straight for driving, twin_slow_turn for the others), every twin too
#        pool      DIR from `tools/drift_pool.sh DIR`: ROOM, the odometry's end-point error
#                  (deg) and the per-pair eps (mrad) of `omnipose-eval --drift`
#        loops     DIR from `tools/loop_benchmark.sh DIR`: ROOM, the sum over the 20
#                  straights of the five laps of |yaw error| (deg; tools/drift/segment_errors.py)
#                  and the per-pair eps (mrad)
#        accuracy  DIR from `METHODS=ifmi tools/accuracy_benchmark.sh DIR`: SEQUENCE and its eps
# Environment: BUILD_DIR [build] (omnipose-replay and omnipose-eval in BUILD_DIR/bin).
# Writes only under ${TMPDIR:-/tmp}; nothing is sent on the network.
set -euo pipefail
[ $# -ge 2 ] || { sed -n '7,18p' "$0" >&2; exit 2; }
kind=$1 dir=${2%/}
shift 2
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../../.." && pwd)
bin=${BUILD_DIR:-$repo/build}/bin
work=$(mktemp -d "${TMPDIR:-/tmp}/replay_with_env.XXXXXX")
trap 'rm -rf "$work"' EXIT

vars=()
keys=()
for arg in "$@"; do
  case $arg in
    pipeline.*=*) keys+=("  ${arg#pipeline.}") ;;
    *) vars+=("$arg") ;;
  esac
done
keys=("${keys[@]/=/: }")

# eps_of GROUNDTRUTH TUM: omnipose-eval's RMS of the per-pair eps, mrad (as
# tools/people_benchmark.sh reads it).
eps_of() {
  "$bin/omnipose-eval" "$1" "$2" --json "$work/eval.json" > /dev/null
  python3 -c 'import json, sys; print("%.5f" % (1e3 * json.load(open(sys.argv[1]))[0]["eps"]["rmse"]))' \
    "$work/eval.json"
}

# replay DATASET CONFIG OPTION...: omnipose-replay with the variables set and the output OPTIONs.
replay() {
  local dataset=$1 config=$2
  shift 2
  if [ ${#keys[@]} -gt 0 ]; then
    grep -q '^pipeline:' "$config" ||
      { echo "replay_with_env.sh: $config has no pipeline: section" >&2; exit 1; }
    { sed -n '0,/^pipeline:/p' "$config"; printf '%s\n' "${keys[@]}"; sed '0,/^pipeline:/d' "$config"; } \
      > "$work/config.yaml"
    config=$work/config.yaml
  fi
  env "${vars[@]}" "$bin/omnipose-replay" "$dataset" --config "$config" --quiet "$@" \
    > /dev/null 2> "$work/replay.log" ||
    { echo "omnipose-replay failed on $dataset, see below" >&2; cat "$work/replay.log" >&2; exit 1; }
}

case $kind in
  people)
    for d in "$dir"/*/*/; do
      [ -d "$d/dataset" ] || continue
      replay "$d/dataset" "$dir/default.yaml" --out "$work/est.tum"
      rel=${d#"$dir"/}
      printf '%s\t%s\n' "${rel%/}" "$(eps_of "$d/dataset/groundtruth.tum" "$work/est.tum")"
    done > "$work/eps.tsv"
    python3 - "$work/eps.tsv" <<'PY'
import sys
eps = dict(line.split("\t") for line in open(sys.argv[1]).read().split("\n") if line)
for key in sorted(eps):
    scene, name = key.split("/")
    if name.startswith("twin"):
        print("%s\t%s" % (key, eps[key]))
        continue
    twin = "%s/twin_%s" % (scene, "straight" if name == "driving" else "slow_turn")
    print("%s\t%s\t%.3f" % (key, eps[key], float(eps[key]) / float(eps[twin])))
PY
    ;;
  pool)
    for d in "$dir"/*/; do
      [ -d "$d/dataset" ] || continue
      replay "$d/dataset" "$dir/default.yaml" --out-odometry "$work/odo.tum"
      "$bin/omnipose-eval" --drift "$d/dataset/groundtruth.tum" "$work/odo.tum" |
        awk -v room="$(basename "$d")" '/end-point/{e=$4} /per-pair eps/{p=$4} END{print room "\t" e "\t" p}'
    done
    ;;
  loops)
    for d in "$dir"/*/; do
      [ -d "$d/dataset" ] || continue
      replay "$d/dataset" "$dir/replay.yaml" --out-odometry "$work/odo.tum" --relative "$work/rel.csv"
      straights=$(python3 "$repo/tools/drift/segment_errors.py" "$repo/tools/drift/rectangle_5laps.yaml" \
                    "$d/dataset/groundtruth.tum" "$work/rel.csv" |
                  awk '/^segment/ && /translation/{y = $(NF - 1); s += (y < 0 ? -y : y)} END{printf "%.3f", s}')
      eps=$("$bin/omnipose-eval" --drift "$d/dataset/groundtruth.tum" "$work/odo.tum" | awk '/per-pair eps/{print $4}')
      printf '%s\t%s\t%s\n' "$(basename "$d")" "$straights" "$eps"
    done
    ;;
  accuracy)
    for d in "$dir"/*/; do
      [ -d "$d/dataset" ] || continue
      replay "$d/dataset" "$dir/replay.yaml" --out "$work/est.tum"
      printf '%s\t%s\n' "$(basename "$d")" "$(eps_of "$d/dataset/groundtruth.tum" "$work/est.tum")"
    done
    ;;
  *) echo "replay_with_env.sh: unknown KIND '$kind' (people, pool, loops or accuracy)" >&2; exit 2 ;;
esac
