#!/usr/bin/env bash
# Whole-process compile of the same 45,000-point helix with host-tools (default checks on) and
# with FullControl 0.1.2 from PyPI (issue 15). Not run in CI: it installs FullControl into the
# ignored folder .hosts/fullcontrol and needs a release build of host-tools.
#
#   bash scripts/bench-fullcontrol.sh [RUNS]      (default 5 runs each, after one warm-up)
#
# Prints the median user+system CPU seconds and wall seconds of each command (GNU time), and
# the ratio of the medians. The designs are the same helix: centre (117.5, 117.5), radius 20 mm,
# 150 turns of 0.2 mm, 45,000 segments, 0.2 mm² strings.
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-5}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

venv=.hosts/fullcontrol
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q fullcontrol==0.1.2
fi
cargo build -q --release -p host-tools
ht=target/release/host-tools

cat > "$work/helix_points.rhai" <<'RHAI'
// The helix from points (FullControl's way): helix_z + polyline.
let t = turtle(point(117.5, 117.5, 0.2));
t.set_cross_section(0.2);
t.polyline(helix_z(point(117.5, 117.5, 0.2), 20, 20, 0, 150, 0.2, 45000));
t
RHAI
cat > "$work/helix_part.rhai" <<'RHAI'
// The same helix as the built-in part.
helix(#{ cx: 117.5, cy: 117.5, z0: 0.2, radius: 20, pitch: 0.2, turns: 150, per_turn: 300 })
RHAI
cat > "$work/helix_fc.py" <<'PY'
import sys
import fullcontrol as fc
steps = fc.helixZ(fc.Point(x=117.5, y=117.5, z=0.2), 20, 20, 0, 150, 0.2, 45000)
gcode = fc.transform(steps, 'gcode', fc.GcodeControls(printer_name='generic', initialization_data={'extrusion_width': 1.0, 'extrusion_height': 0.2}), show_tips=False)
open(sys.argv[1], 'w').write(gcode)
PY

# median of the numbers on stdin
median() { sort -g | awk '{a[NR]=$1} END {print (NR%2 ? a[(NR+1)/2] : (a[NR/2]+a[NR/2+1])/2)}'; }

measure() { # name, command...
    local name=$1; shift
    "$@" >/dev/null 2>&1 # warm-up
    : > "$work/$name.times"
    for _ in $(seq "$runs"); do
        /usr/bin/time -f '%U %S %e' -a -o "$work/$name.times" "$@" >/dev/null 2>&1
    done
    local cpu wall
    cpu=$(awk '{print $1 + $2}' "$work/$name.times" | median)
    wall=$(awk '{print $3}' "$work/$name.times" | median)
    echo "$name $cpu $wall"
    printf '%-34s median CPU %6.3f s   median wall %6.3f s   (%s runs)\n' "$name" "$cpu" "$wall" "$runs" >&2
}

a=$(measure host-tools-points "$ht" compile "$work/helix_points.rhai" -o "$work/points.gcode")
b=$(measure host-tools-helix-part "$ht" compile "$work/helix_part.rhai" -o "$work/part.gcode")
c=$(measure fullcontrol-0.1.2 "$venv/bin/python" "$work/helix_fc.py" "$work/fc.gcode")
fc_cpu=$(echo "$c" | awk '{print $2}')
for r in "$a" "$b"; do
    echo "$r" | awk -v f="$fc_cpu" '{printf "FullControl / %s: %.1fx CPU\n", $1, f / $2}'
done
grep -c '^G1' "$work/points.gcode" "$work/part.gcode" "$work/fc.gcode" | sed 's/^.*\//G1 lines in /'
