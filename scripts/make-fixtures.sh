#!/usr/bin/env bash
# Regenerate the real-slicer G-code fixtures in tests/fixtures/slicer/ (committed; the slicers'
# output differs slightly from run to run, so tests read the committed files).
#
#   scripts/make-fixtures.sh            # needs prusa-slicer, openscad; cura-engine and slic3r optional
#
# Install on Debian 12: apt-get install -y prusa-slicer openscad cura-engine slic3r
# CuraEngine needs Cura's printer definitions (fdmprinter.def.json), shipped in Debian's `cura`
# package: set CURA_DEFS to their directory, or the script fetches the package with
# `apt-get download cura` into a temporary directory and unpacks only the definitions.
set -euo pipefail

here="$(cd "$(dirname "$0")/.." && pwd)"
out="$here/tests/fixtures/slicer"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# 1. The part: OpenSCAD source -> STL.
openscad -o "$tmp/part.stl" "$out/part.scad" 2>/dev/null
echo "part.stl: $(stat -c %s "$tmp/part.stl") bytes"

# 2. PrusaSlicer, default print settings (they write ;LAYER_CHANGE / ;Z: / ;HEIGHT:), 0.2 mm layers.
prusa-slicer --export-gcode --layer-height 0.2 --first-layer-height 0.2 --center 100,100 \
    -o "$out/prusaslicer.gcode" "$tmp/part.stl" >/dev/null 2>&1
echo "prusaslicer.gcode: $(grep -c '^;LAYER_CHANGE' "$out/prusaslicer.gcode") layers"

# 3. CuraEngine 4.13 (;LAYER:n from 0, Z move before the marker), if installed.
if command -v CuraEngine >/dev/null; then
    defs="${CURA_DEFS:-/usr/share/cura/resources/definitions}"
    if [ ! -f "$defs/fdmprinter.def.json" ]; then
        (cd "$tmp" && apt-get download cura >/dev/null 2>&1 && dpkg -x cura_*.deb cura)
        defs="$tmp/cura/usr/share/cura/resources/definitions"
    fi
    CURA_ENGINE_SEARCH_PATH="$defs:$(dirname "$defs")/extruders" \
        CuraEngine slice -j "$defs/fdmprinter.def.json" \
        -s layer_height=0.2 -s machine_width=235 -s machine_depth=235 -s machine_height=250 \
        -s center_object=true -l "$tmp/part.stl" -o "$out/cura.gcode" >/dev/null 2>&1
    echo "cura.gcode: $(grep -c '^;LAYER:' "$out/cura.gcode") layers"
fi

# 4. Slic3r 1.3 (no layer comments at all: only Z moves), if installed.
if command -v slic3r >/dev/null; then
    slic3r --layer-height 0.2 --first-layer-height 0.2 --print-center 100,100 \
        -o "$out/slic3r.gcode" "$tmp/part.stl" >/dev/null 2>&1
    echo "slic3r.gcode: $(grep -c '^G1 Z[0-9.]* F' "$out/slic3r.gcode") Z moves"
fi
ls -la "$out"
