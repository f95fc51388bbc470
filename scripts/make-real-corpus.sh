#!/usr/bin/env bash
# Rebuild the real-file layer corpus (docs/testing.md, "The real-file corpus";
# tests/fixtures/realworld/SOURCES.md) from the two public repositories it comes from, at the
# commits named there. It reads git directories you already have (no network here):
#
#   scripts/make-real-corpus.sh KAGEURUFU_GIT_DIR DISPLAYLAYERPROGRESS_GIT_DIR OUT_DIR
#
# KAGEURUFU_GIT_DIR: kageurufu/preprocess_cancellation; DISPLAYLAYERPROGRESS_GIT_DIR:
# OllisGit/OctoPrint-DisplayLayerProgress. Each file is trimmed to its first layers and its end
# code by `cargo run -p layerref --example trim` (which says in the file's first line what it
# kept), and two are given MatterControl-style levelling by scripts/level-gcode.py.
set -euo pipefail
k="$1"; d="$2"; out="$3"
here="$(cd "$(dirname "$0")/.." && pwd)"
mkdir -p "$out"
tmp="$(mktemp -d)"; trap 'rm -rf "$tmp"' EXIT
K_HEAD=3b9cf647f9088d51d5ae637e3e61bb9f68e0c3d0
K_S3D=433ee2c3b8c9b06b28374818af3835b207224174
K_PYR=6715a51e89a2642ce39bbf05638d3568a5df98cb
D_HEAD=dbeb03d223ce68797535e30850e7446db55526f8
# name  repo  commit  path
while read -r name repo commit path; do
  [ -z "$name" ] && continue
  git -C "$repo" show "$commit:$path" > "$tmp/$name"
  (cd "$here" && cargo run -q --release -p layerref --example trim -- \
     "$tmp/$name" "$out/$name" --layers 5 --max-bytes 120000)
done <<LIST
cura.gcode $k $K_HEAD GCode/cura.gcode
ideamaker.gcode $k $K_HEAD GCode/ideamaker.gcode
prusaslicer.gcode $k $K_HEAD GCode/prusaslicer.gcode
prusaslicer-issue1.gcode $k $K_HEAD GCode/prusaslicer-issue1.gcode
m486.gcode $k $K_HEAD GCode/m486.gcode
slic3r.gcode $k $K_HEAD GCode/slic3r.gcode
superslicer.gcode $k $K_HEAD GCode/superslicer.gcode
icesl.gcode $k $K_HEAD GCode/unsupported/icesl.gcode
kirimoto.gcode $k $K_HEAD GCode/unsupported/kirimoto.gcode
kisslicer.1.6.3.gcode $k $K_HEAD GCode/unsupported/kisslicer.1.6.3.gcode
kisslicer.2.0.6.gcode $k $K_HEAD GCode/unsupported/kisslicer.2.0.6.gcode
simplify3d.gcode $k $K_S3D GCode/simplify3d.gcode
pyramid_cura.gcode $k $K_PYR GCode/inverted_pyramid/cura.gcode
pyramid_ideamaker.gcode $k $K_PYR GCode/inverted_pyramid/ideamaker.gcode
pyramid_superslicer.gcode $k $K_PYR GCode/inverted_pyramid/superslicer.gcode
tapered_superslicer.gcode $k $K_PYR GCode/tapered_cube_superslicer.gcode
s3d302.gcode $d $D_HEAD testdata/issue23/03_Simplify3D_ukazovátko.gcode
s3d400_bamarillo.gcode $d $D_HEAD testdata/issue36/bamarillo.gcode
cura321.gcode $d $D_HEAD testdata/issue23/AE10EFPI3_f51e2615-0835-476c-989f-18c7c7eeb2f4.gcode
cura350.gcode $d $D_HEAD testdata/issue73/usbcap-cura.gcode
curale369.gcode $d $D_HEAD testdata/issue76/LTAZ6A_20x20x5mm-Cube.gcode
ideamaker340.gcode $d $D_HEAD testdata/issue73/20mm_Calibration_Box.gcode
slic3rpe1372.gcode $d $D_HEAD testdata/issue42/small.spool.outside.gcode
LIST
python3 "$here/scripts/level-gcode.py" "$out/slic3r.gcode" "$out/levelled-slic3r.gcode"
python3 "$here/scripts/level-gcode.py" "$out/curale369.gcode" "$out/levelled-curale369.gcode" \
  --tilt-x -0.15 --tilt-y 0.25 --offset 0.05
ls -l "$out"
