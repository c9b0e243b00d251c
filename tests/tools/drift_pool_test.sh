#!/usr/bin/env bash
# tools/drift_pool.sh in its quick mode (8 frames of each room, 1 x 1 rays): every room is
# rendered, replayed with the defaults and a variant and scored, and the table has a row per
# room and the median and worst of each group. Usage: drift_pool_test.sh SOURCE_DIR BUILD_DIR
set -euo pipefail
src=$1
build=$(realpath "$2")
cd "$src"
bash -n tools/drift_pool.sh
rc=0
out=$(bash tools/drift_pool.sh --frobnicate 2>&1) || rc=$?
[ "$rc" = 2 ] || { echo "drift_pool.sh --frobnicate: exit $rc, expected 2: $out" >&2; exit 1; }
if [ ! -f ../shared/data/equirect/park_theta_v_5376x2688.jpg ]; then
  echo "drift_pool.sh: syntax and usage checked (no park photo beside the repository)"
  exit 0
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
BUILD_DIR=$build FRAMES=8 VARIANTS="keyframes.slots: 0|plane_depth_prior: false; keyframes.anchor_gain: 0.5" \
  bash tools/drift_pool.sh "$tmp/pool" > "$tmp/log" 2>&1 || {
  echo "drift_pool.sh failed:" >&2; tail -20 "$tmp/log" >&2; exit 1; }
table=$tmp/pool/DRIFT_POOL.md
rooms=$(grep -cE '^\| [a-z_0-9]+ \| (tuning|report-only) \|' "$table")
summaries=$(grep -cE '^\| \*\*(median|worst)\*\* \|' "$table")
[ "$rooms" = 9 ] || { echo "DRIFT_POOL.md: $rooms room rows, expected 9" >&2; cat "$table" >&2; exit 1; }
[ "$summaries" = 4 ] || { echo "DRIFT_POOL.md: $summaries summary rows, expected 4" >&2; exit 1; }
grep -qF 'variant2: `plane_depth_prior: false; keyframes.anchor_gain: 0.5`' "$table" ||
  { echo "DRIFT_POOL.md does not name its second variant" >&2; exit 1; }
grep -qx 'keyframes:' "$tmp/pool/variant1.yaml" && grep -qx '  slots: 0' "$tmp/pool/variant1.yaml" ||
  { echo "variant1.yaml lacks its keyframes section:" >&2; cat "$tmp/pool/variant1.yaml" >&2; exit 1; }
grep -qx '  plane_depth_prior: false' "$tmp/pool/variant2.yaml" &&
  grep -qx '  anchor_gain: 0.5' "$tmp/pool/variant2.yaml" ||
  { echo "variant2.yaml lacks a key:" >&2; cat "$tmp/pool/variant2.yaml" >&2; exit 1; }
# Every cell a number: six per row (default and two variants, end-point and eps).
if grep -E '^\| ' "$table" | grep -vE '^\| (room|\*\*|[a-z_0-9]+ \| (tuning|report-only))' | grep -q .; then
  echo "DRIFT_POOL.md: unexpected rows" >&2; exit 1
fi
bad=$(grep -E '\| (tuning|report-only) \|' "$table" | awk -F'|' '{for (i = 4; i <= 9; i++) if ($i !~ /^ [0-9]+\.[0-9]+ $/) print}' | wc -l)
[ "$bad" = 0 ] || { echo "DRIFT_POOL.md: cells that are not numbers" >&2; cat "$table" >&2; exit 1; }
echo "drift_pool.sh: 9 rooms x 3 settings scored in quick mode"
