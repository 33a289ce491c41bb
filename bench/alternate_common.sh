# Sourced by the benches that reconstruct scans alternately in two modes (prepare_ahead.sh,
# ab_reconstruct.sh): their shared options, parsed from "$@", and the median of a list.
# The sourcing script sets `out` and `extra` (its defaults) and `usage` (the sed range of its
# header comment) first; afterwards build, out, rounds, scans, rig, extra and heatwave are set.
#   [--build DIR] [--out DIR] [--rounds N] --scans "SCAN ..." [--rig RIG] [--args "ARGS"]
build=build
scans=""
rig=""
rounds=3
while [ $# -gt 0 ]; do
  case "$1" in
    --build) build=$2; shift 2 ;;
    --out) out=$2; shift 2 ;;
    --rounds) rounds=$2; shift 2 ;;
    --scans) scans=$2; shift 2 ;;
    --rig) rig=$2; shift 2 ;;
    --args) extra=$2; shift 2 ;;
    -h|--help) sed -n "${usage}p" "$0"; exit 0 ;;
    *) echo "unknown argument $1" >&2; exit 2 ;;
  esac
done
[ -n "$scans" ] || { echo "--scans is required" >&2; exit 2; }
heatwave="$build/cli/heatwave"
mkdir -p "$out"
# Median of whitespace-separated numbers on stdin.
median() { tr ' ' '\n' | grep -v '^$' | sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
