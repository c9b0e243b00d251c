# shellcheck shell=bash
# What the benchmark scripts (tools/accuracy_benchmark.sh, drift_benchmark.sh, drift_pool.sh,
# real_camera_benchmark.sh, loop_benchmark.sh, people_benchmark.sh) share: their arguments, the
# command line their reports quote, the programs they need, the lens calibrations and motion
# scripts they write and the entries they pick by name. Sourcing it sets the strict mode (set -euo pipefail) and makes
# the repository's top directory the working directory and `root`.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

# bench_args NAME OUTDIR_NAME [--FLAG ...] -- ARGS...: parses the script's ARGS: --publish
# (publish=1), -h/--help (prints the script's header comment and exits 0), one OUTDIR (out;
# default $build/OUTDIR_NAME), and each --FLAG listed before `--` (sets the variable FLAG,
# without the dashes, to 1; it starts at 0). Anything else is a usage error naming NAME
# (exit 2). Sets build (BUILD_DIR, default build) and data (DATA_DIR, default
# ../shared/data/equirect beside the repository).
bench_args() {
  local name=$1 default_out=$2 arg flag
  shift 2
  local -a flags=()
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do flags+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  publish=0
  out=""
  for flag in "${flags[@]}"; do printf -v "${flag#--}" '%s' 0; done
  for arg in "$@"; do
    case "$arg" in
      --publish) publish=1 ;;
      -h|--help) sed -n '2,/^source /p' "$0" | grep '^#' | grep -v '^# shellcheck' |
                   sed 's/^# \{0,1\}//'; exit 0 ;;
      -*)
        for flag in "${flags[@]}"; do
          if [ "$arg" = "$flag" ]; then printf -v "${flag#--}" '%s' 1; continue 2; fi
        done
        echo "$name: unknown option $arg" >&2
        exit 2
        ;;
      *) [ -z "$out" ] || { echo "$name: one OUTDIR only" >&2; exit 2; }; out=$arg ;;
    esac
  done
  build=${BUILD_DIR:-build}
  data=${DATA_DIR:-$PWD/../shared/data/equirect}
  out=${out:-$build/$default_out}
}

# bench_command_line SCRIPT ARGS... -- VAR...: sets command_line to "SCRIPT ARGS", preceded by
# VAR=value for every environment variable VAR that is set (what the report says was run).
bench_command_line() {
  local -a args=()
  command_line=$1
  shift
  while [ $# -gt 0 ] && [ "$1" != "--" ]; do args+=("$1"); shift; done
  [ $# -gt 0 ] && shift
  [ ${#args[@]} -gt 0 ] && command_line="$command_line ${args[*]}"
  local var
  for var in "$@"; do
    [ -n "${!var:-}" ] && command_line="$(bench_assignment "$var") $command_line"
  done
  return 0
}

# bench_assignment VAR: prints VAR=value for the report's command line, the value
# single-quoted when a shell would split or expand it, so the line can be pasted back.
bench_assignment() {
  local value=${!1:-}
  [[ "$value" =~ ^[A-Za-z0-9_./:,=+@%-]+$ ]] || value="'${value//\'/\'\\\'\'}'"
  printf '%s=%s' "$1" "$value"
}

# bench_ifmi_pipeline NAME: the entries of IFMI_PIPELINE ("key: value" entries of
# daemon.yaml's `pipeline:` section separated by ';', e.g. "noise_weighting: true") as YAML
# lines of that section (two spaces of indent) in ifmi_pipeline_yaml, empty when unset.
# When set, command_line (bench_command_line) is prefixed with it, and --publish is a usage
# error naming NAME (exit 2): the published results are those of the defaults.
bench_ifmi_pipeline() {
  local name=$1
  ifmi_pipeline_yaml=""
  [ -n "${IFMI_PIPELINE:-}" ] || return 0
  command_line="$(bench_assignment IFMI_PIPELINE) $command_line"
  if [ "$publish" = 1 ]; then
    echo "$name: --publish publishes the defaults; unset IFMI_PIPELINE" >&2
    exit 2
  fi
  ifmi_pipeline_yaml=$(bench_pipeline_lines "$IFMI_PIPELINE")
  [ -n "$ifmi_pipeline_yaml" ] && ifmi_pipeline_yaml+=$'\n'
  return 0
}

# bench_pipeline_lines ENTRIES: "key: value" entries of daemon.yaml's `pipeline:` section
# separated by ';' printed as YAML lines of that section (two spaces of indent), blank
# entries skipped.
bench_pipeline_lines() {
  local entry
  local -a entries=()
  IFS=';' read -ra entries <<< "$1"
  for entry in "${entries[@]}"; do
    entry=$(sed 's/^[[:space:]]*//; s/[[:space:]]*$//' <<< "$entry")
    [ -n "$entry" ] && printf '  %s\n' "$entry"
  done
  return 0
}

# bench_ocamcalib_calibration FILE OCAMCALIB_FILE: writes FILE, a calibration.yaml for the
# OCamCalib lens of OCAMCALIB_FILE (an absolute path) with the paper's panorama (1100 x 110,
# horizon row 54.5), as every benchmark renders and replays it.
bench_ocamcalib_calibration() {
  cat > "$1" <<YAML
omni:
  model: ocamcalib
  ocamcalib_file: $2
  azimuth_zero_deg: 0.0
  azimuth_direction: ccw
panorama: {width: 1100, height: 110, horizon_row: 54.5, forward_column: 0.0}
YAML
}

# bench_tools [--require NAME] BUILD_DIR PROGRAM...: builds the programs missing from
# BUILD_DIR/bin (a Release build with Ninja, configured when needed); with --require, a
# missing program is an error naming it and how to build it (exit 1) instead.
bench_tools() {
  local require="" t
  if [ "$1" = "--require" ]; then require=$2; shift 2; fi
  local build=$1
  shift
  local -a missing=()
  for t in "$@"; do [ -x "$build/bin/$t" ] || missing+=("$t"); done
  [ ${#missing[@]} -eq 0 ] && return 0
  if [ -n "$require" ]; then
    echo "$require: missing $build/bin/${missing[0]} (build it: cmake --build $build --target $*; or set BUILD_DIR)" >&2
    exit 1
  fi
  echo "== building $* in $build"
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$build" -j"$(nproc 2>/dev/null || echo 2)" --target "$@"
}

# bench_version BIN_DIR: sets `version` to what the build under test says of itself
# (`omnipose-replay --version`), which a published report names beside its command and date.
bench_version() {
  version=$("$1/omnipose-replay" --version 2>/dev/null || echo "omnipose (version unknown)")
}

# bench_fresh_out NAME [SUBDIR...]: sets `start` (epoch seconds) and `load_start` (the load
# averages, for the report), then empties OUTDIR `out` and creates it with the subfolders
# given. Refuses (exit 2, naming NAME) to clear /, the repository `root` or $HOME.
bench_fresh_out() {
  local name=$1 d
  shift
  start=$(date +%s)
  load_start=$(cut -d' ' -f1-3 /proc/loadavg)
  case "$(cd "$(dirname "$out")" 2>/dev/null && pwd)/$(basename "$out")" in
    /|"$root"|"$root/"|"$root/."|"$HOME") echo "$name: refusing to clear $out" >&2; exit 2 ;;
  esac
  rm -rf "$out"
  mkdir -p "$out"
  for d in "$@"; do mkdir -p "$out/$d"; done
}

# bench_pick NAME WHAT NAMES ENTRY...: sets the array `picked` to the entries ("name|...")
# named in NAMES (separated by spaces, in that order), or to every entry when NAMES is empty.
# A name that no entry has is a usage error: "NAME: no WHAT named N" (exit 2).
bench_pick() {
  local script=$1 what=$2 names=$3 entry name found
  shift 3
  picked=()
  if [ -z "$names" ]; then picked=("$@"); return 0; fi
  for name in $names; do
    found=""
    for entry in "$@"; do [ "${entry%%|*}" = "$name" ] && found=$entry; done
    [ -n "$found" ] || { echo "$script: no $what named $name" >&2; exit 2; }
    picked+=("$found")
  done
}

# The robot's gyro the benchmarks render beside their frames (omnipose-synth flags; the rate
# is each benchmark's, --gyro-rate HZ): a phone-class MEMS gyro, white noise 0.005
# deg/s/sqrt(Hz), bias 0.5 deg/s, its clock 12.3 ms behind the camera's, mounted 40 deg off the
# camera's axes. The frames stay bit-identical with or without it.
bench_gyro_model="--gyro-noise 8.7e-5 --gyro-bias 0.0087 --gyro-time-offset 0.0123"
bench_gyro_model+=" --gyro-rotation 0.939692621,0.228013429,-0.228013429,0.114006714"

# bench_slow_turn_motion FILE FRAMES: writes the motion script `slow_turn` (the robot turning
# slowly in place, yaw 0.3..0.6 deg/frame, positive, drawn per frame) of FRAMES frames to FILE.
bench_slow_turn_motion() {
  cat > "$1" <<YAML
# The robot turning slowly: yaw 0.3..0.6 deg/frame, positive, drawn per frame.
seed: 0
frame_rate: 30
frames: $2
segments:
  - frames: $(($2 - 1))
    rotation: {axis: z, step_deg: [0.3, 0.6], sign: positive}
YAML
}
