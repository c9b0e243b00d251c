# The pool of box rooms the driving benchmarks render (tools/drift_pool.sh,
# tools/loop_benchmark.sh), defined once. Sourced; needs $root, $data (the park photo's
# folder) and $bin.
#   tuning rooms       indoor photo as it is, turned 90, mirrored and turned 200; the park photo
#                      (at 2048 x 1024) as it is and turned 120; the office texture (the real
#                      mirror image of tests/data/catadioptric resampled by omnipose-equirect)
#                      as it is and mirrored and turned 180
#   report-only rooms  indoor turned 270; park mirrored and turned 240. Reported, never used to
#                      choose a setting.

# pool_rooms OUTDIR: makes the office texture in OUTDIR/lenses (with that mirror's
# calibration) and sets `rooms`, one "name|group|photo|omnipose-synth texture options" entry
# per room. Exits naming a missing input.
pool_rooms() {
  local lenses=$1/lenses
  local indoor=$root/tests/data/equirect/indoor_1024x512.jpg
  local park=$data/park_theta_v_5376x2688.jpg
  local catadioptric=$root/tests/data/catadioptric
  local f
  for f in "$indoor" "$park" "$catadioptric/mirror_office_1920x1080.jpg"; do
    [ -f "$f" ] || { echo "pool_rooms: missing $f" >&2; exit 1; }
  done
  mkdir -p "$lenses"
  bench_ocamcalib_calibration "$lenses/mirror_office.yaml" "$catadioptric/mirror_office_ocamcalib.txt"
  local office=$lenses/office_texture.png
  "$bin/omnipose-equirect" --omni "$catadioptric/mirror_office_1920x1080.jpg" \
    --calibration "$lenses/mirror_office.yaml" --out "$office" --width 2048 \
    > "$lenses/office_texture.log"
  rooms=(
    "indoor|tuning|$indoor|"
    "indoor_t90|tuning|$indoor|--texture-turn 90"
    "indoor_m200|tuning|$indoor|--texture-mirror --texture-turn 200"
    "park|tuning|$park|--texture-width 2048"
    "park_t120|tuning|$park|--texture-width 2048 --texture-turn 120"
    "office|tuning|$office|"
    "office_m180|tuning|$office|--texture-mirror --texture-turn 180"
    "indoor_t270|report-only|$indoor|--texture-turn 270"
    "park_m240|report-only|$park|--texture-width 2048 --texture-mirror --texture-turn 240"
  )
}
