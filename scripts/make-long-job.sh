#!/usr/bin/env bash
# A long slicer job for the sim's memory benchmark (docs/sim.md, "Memory and speed on long
# jobs"): PrusaSlicer's fixture (tests/fixtures/slicer/prusaslicer.gcode, 0.2 MB, 696 s of
# printing) repeated until the file reaches SIZE_MB megabytes. Each copy is a whole print
# (start code, heat-up, layers, end code), as a print farm's queue of the same part would send.
# Usage: bash scripts/make-long-job.sh SIZE_MB OUT.gcode
set -euo pipefail
cd "$(dirname "$0")/.."
size_mb=${1:?size in MB}
out=${2:?output file}
src=tests/fixtures/slicer/prusaslicer.gcode
want=$((size_mb * 1000 * 1000))
: >"$out"
while [ "$(stat -c %s "$out")" -lt "$want" ]; do
  cat "$src" >>"$out"
done
echo "$out: $(stat -c %s "$out") bytes, $(wc -l <"$out") lines"
