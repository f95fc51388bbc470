#!/usr/bin/env bash
# Regenerate the layer corpus in tests/fixtures/corpus/ (committed; not run in CI): small shapes
# sliced by Debian's slicers in the modes that stress layer detection (issue 14) — vase/spiral,
# sequential (complete objects), variable layer height, Z-hop and support — with the slicers'
# comments kept. tests/tests/layer_corpus.rs reads the committed files (and strips the comments
# itself for the comment-free mode, as OctoPrint and printcore send them).
#
#   scripts/make-corpus.sh        # needs prusa-slicer, slic3r, cura-engine (Debian 12)
#
# Install: apt-get install -y --no-install-recommends prusa-slicer slic3r cura-engine
# CuraEngine needs Cura's printer definitions (fdmprinter.def.json) from Debian's `cura` package:
# set CURA_DEFS to their directory, or the script fetches the package with `apt-get download cura`
# into a temporary directory and unpacks only the definitions.
#
# Layers are 0.3 mm and the shapes a few mm tall, so the corpus stays small (well under 1 MB).
set -euo pipefail

here="$(cd "$(dirname "$0")/.." && pwd)"
out="${CORPUS_OUT:-$here/tests/fixtures/corpus}"
mkdir -p "$out"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# 1. The shapes, as ASCII STL written here (no CAD tool needed):
#    cup   — a 24-sided cylinder r 8 mm, h 5 mm (vase mode);
#    block — a 10 x 10 x 3 mm box (sequential, Z-hop);
#    tee   — a 4 x 4 x 3 mm post under a 16 x 4 x 1.2 mm bar (an overhang: support; its
#            slope-free walls and overhang also give Cura's adaptive layers something to vary).
python3 - "$tmp" <<'PY'
import math, sys
d = sys.argv[1]

def box(x0, y0, z0, x1, y1, z1):
    v = [(x, y, z) for z in (z0, z1) for y in (y0, y1) for x in (x0, x1)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return [(v[a], v[b], v[c]) for q in quads for (a, b, c) in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]

def cylinder(r, h, n):
    t = []
    for i in range(n):
        a0, a1 = 2 * math.pi * i / n, 2 * math.pi * (i + 1) / n
        p0 = (r * math.cos(a0), r * math.sin(a0))
        p1 = (r * math.cos(a1), r * math.sin(a1))
        t.append(((0, 0, 0), (p1[0], p1[1], 0), (p0[0], p0[1], 0)))
        t.append(((0, 0, h), (p0[0], p0[1], h), (p1[0], p1[1], h)))
        t.append(((p0[0], p0[1], 0), (p1[0], p1[1], 0), (p1[0], p1[1], h)))
        t.append(((p0[0], p0[1], 0), (p1[0], p1[1], h), (p0[0], p0[1], h)))
    return t

def write(name, tris):
    with open(f"{d}/{name}.stl", "w") as f:
        f.write(f"solid {name}\n")
        for a, b, c in tris:
            f.write(" facet normal 0 0 0\n  outer loop\n")
            for p in (a, b, c):
                f.write("   vertex %.5f %.5f %.5f\n" % p)
            f.write("  endloop\n endfacet\n")
        f.write(f"endsolid {name}\n")

def twisted(profile, h, rings, twist_deg, scale_top):
    # A prism of `profile`, twisted by twist_deg and scaled by scale_top from bottom to top.
    n, out, ring = len(profile), [], []
    for k in range(rings + 1):
        t = k / rings
        a, s = math.radians(twist_deg) * t, 1 + (scale_top - 1) * t
        ring.append([(s * (x * math.cos(a) - y * math.sin(a)), s * (x * math.sin(a) + y * math.cos(a)), h * t)
                     for (x, y) in profile])
    for k in range(rings):
        A, B = ring[k], ring[k + 1]
        for i in range(n):
            j = (i + 1) % n
            out += [(A[i], A[j], B[j]), (A[i], B[j], B[i])]
    for i in range(n):
        j = (i + 1) % n
        out += [((0, 0, 0), ring[0][j], ring[0][i]), ((0, 0, h), ring[-1][i], ring[-1][j])]
    return out

write("cup", cylinder(8, 5, 24))
write("block", box(0, 0, 0, 10, 10, 3))
write("tee", box(6, 0, 0, 10, 4, 3) + box(0, 0, 3, 16, 4, 4.2))
# Issue 21. star: a five-lobed star (48 points, r 10 ± 3 mm) 6 mm tall, twisted 30° and
# narrowing to 85 %: 30 turns of 0.2 mm whose seam moves from turn to turn, a non-convex outline.
star = [((10 + 3 * math.cos(5 * a)) * math.cos(a), (10 + 3 * math.cos(5 * a)) * math.sin(a))
        for a in (2 * math.pi * i / 48 for i in range(48))]
write("star", twisted(star, 6, 12, 30, 0.85))
# plate: 30 x 30 x 1.6 mm, 8 layers of 0.2 mm with 20 % infill: ~170 moves per layer, longer
# than the firmware's command queue (32) and planner ring (64 segments of 0.2 mm).
write("plate", box(0, 0, 0, 30, 30, 1.6))
PY

common_prusa=(--layer-height 0.3 --first-layer-height 0.3 --nozzle-diameter 0.4)

# 2. PrusaSlicer 2.5 (;LAYER_CHANGE / ;Z: / ;HEIGHT:).
if command -v prusa-slicer >/dev/null; then
    ps() { local o="$1"; shift; prusa-slicer --export-gcode "${common_prusa[@]}" "$@" -o "$out/$o" >/dev/null 2>&1 || echo "prusa-slicer failed: $o"; }
    ps prusa-vase.gcode --center 100,100 --spiral-vase --fill-density 0% --perimeters 1 --top-solid-layers 0 --bottom-solid-layers 2 "$tmp/cup.stl"
    ps prusa-sequential.gcode --complete-objects --extruder-clearance-radius 8 --extruder-clearance-height 10 \
        --duplicate 3 --duplicate-distance 12 "$tmp/block.stl"
    ps prusa-zhop.gcode --center 100,100 --retract-lift 0.6 --fill-density 30% "$tmp/block.stl"
    ps prusa-support.gcode --center 100,100 --support-material "$tmp/tee.stl"
fi

# 3. Slic3r 1.3 (no layer comments: only Z moves; --gcode-comments adds per-move comments).
if command -v slic3r >/dev/null; then
    s3() { local o="$1"; shift; slic3r --layer-height 0.3 --first-layer-height 0.3 --nozzle-diameter 0.4 "$@" -o "$out/$o" >/dev/null 2>&1 || echo "slic3r failed: $o"; }
    s3 slic3r-vase.gcode --print-center 100,100 --spiral-vase --perimeters 1 --top-solid-layers 0 --bottom-solid-layers 2 "$tmp/cup.stl"
    s3 slic3r-sequential.gcode --complete-objects --extruder-clearance-radius 8 --extruder-clearance-height 10 \
        --duplicate 2 --duplicate-distance 12 "$tmp/block.stl"
    # (Slic3r 1.3 has no variable layer height: Cura's adaptive layers stand for it below.)
    s3 slic3r-zhop-support.gcode --print-center 100,100 --retract-lift 0.4 --support-material "$tmp/tee.stl"
fi

# 4. CuraEngine 4.13 (;LAYER:n; the Ender-3 style purge line before ;LAYER:0).
if command -v CuraEngine >/dev/null; then
    defs="${CURA_DEFS:-/usr/share/cura/resources/definitions}"
    if [ ! -f "$defs/fdmprinter.def.json" ]; then
        (cd "$tmp" && apt-get download cura >/dev/null 2>&1 && dpkg -x cura_*.deb cura)
        defs="$tmp/cura/usr/share/cura/resources/definitions"
    fi
    # The Ender-3 start code: home, then a purge line at Z 0.28 along the bed edge.
    start='G28\nG92 E0\nG1 Z2.0 F3000\nG1 X0.1 Y20 Z0.3 F5000.0\nG1 X0.1 Y200.0 Z0.3 F1500.0 E15\nG1 X0.4 Y200.0 Z0.3 F5000.0\nG1 X0.4 Y20 Z0.3 F1500.0 E30\nG92 E0\nG1 Z2.0 F3000'
    end='G91\nG1 E-2 F2700\nG1 E-2 Z0.2 F2400\nG1 X5 Y5 F3000\nG1 Z10\nG90\nG1 X0 Y235\nM106 S0\nM104 S0\nM140 S0\nM84 X Y E'
    cura() {
        local o="$1"; shift
        CURA_ENGINE_SEARCH_PATH="$defs:$(dirname "$defs")/extruders" \
            CuraEngine slice -j "$defs/fdmprinter.def.json" \
            -s layer_height=0.3 -s layer_height_0=0.3 -s machine_width=235 -s machine_depth=235 -s machine_height=250 \
            -s machine_start_gcode="$(printf "$start")" -s machine_end_gcode="$(printf "$end")" \
            -s center_object=true "$@" -o "$out/$o" >/dev/null 2>&1 || echo "CuraEngine failed: $o"
    }
    cura cura-vase.gcode -s magic_spiralize=true -s wall_line_count=1 -s top_layers=0 -s bottom_layers=2 -l "$tmp/cup.stl"
    # (No Cura sequential file: CuraEngine 4.13's command line prints one of two meshes with
    # print_sequence=one_at_a_time — it cannot read machine_head_with_fans_polygon from -s.)
    cura cura-variable.gcode -s adaptive_layer_height_enabled=true -s adaptive_layer_height_variation=0.2 \
        -s retraction_hop_enabled=true -s retraction_hop=0.6 -l "$tmp/tee.stl"
    cura cura-support.gcode -s support_enable=true -s support_type=buildplate -l "$tmp/tee.stl"
fi
# 5. Issue 21: every marker family with layers longer than the queues, vases of the three
#    slicers at 0.2 mm with many turns, purge lines.
if command -v prusa-slicer >/dev/null; then
    p2=(--center 100,100 --layer-height 0.2 --first-layer-height 0.2 --nozzle-diameter 0.4)
    ps prusa-vase-star.gcode "${p2[@]}" --spiral-vase --fill-density 0% --perimeters 1 --top-solid-layers 0 \
        --bottom-solid-layers 2 "$tmp/star.stl"
    # The marker families, with PrusaSlicer 2.5's motion and its layer G-code templates (the
    # placeholders PrusaSlicer, Orca and the Klipper profiles use): Klipper's macro and M73 L
    # after PrusaSlicer's own ;LAYER_CHANGE (as Orca and PrusaSlicer-for-Klipper files have
    # both); Simplify3D's and ideaMaker's comments instead of PrusaSlicer's (its ;LAYER_CHANGE,
    # ;Z:, ;HEIGHT: triple and its header removed; ideaMaker's header written).
    ps family-klipper.gcode "${p2[@]}" --fill-density 20% \
        --layer-gcode 'SET_PRINT_STATS_INFO CURRENT_LAYER={layer_num + 1}' "$tmp/plate.stl"
    ps family-m73.gcode "${p2[@]}" --fill-density 20% --layer-gcode 'M73 L{layer_num + 1}' "$tmp/plate.stl"
    drop_prusa_markers() { awk 'skip > 0 { skip--; next } $0 == ";LAYER_CHANGE" { skip = 2; next } /^; generated by PrusaSlicer/ { next } { print }'; }
    ps s3d.tmp "${p2[@]}" --fill-density 20% \
        --before-layer-gcode '; layer {layer_num + 1}, Z = {layer_z}' "$tmp/plate.stl"
    drop_prusa_markers < "$out/s3d.tmp" > "$out/family-s3d.gcode"
    ps idea.tmp "${p2[@]}" --fill-density 20% \
        --before-layer-gcode $';LAYER:{layer_num}\n;Z:{layer_z}\n;HEIGHT:0.2' "$tmp/plate.stl"
    { echo ";Sliced by ideaMaker (its layer markers on PrusaSlicer 2.5's motion: scripts/make-corpus.sh)"
      drop_prusa_markers < "$out/idea.tmp"; } > "$out/family-ideamaker.gcode"
    rm -f "$out/s3d.tmp" "$out/idea.tmp"
    # A purge line (intro line) at the first layer's height before the first layer, as
    # PrusaSlicer's MK3S start code prints it (moved inside an Ender-3's bed).
    ps prusa-purge.gcode "${p2[@]}" --fill-density 20% \
        --start-gcode $'G28\nG1 Z0.2 F720\nG1 X1 Y1 F1000\nG92 E0\nG1 X60 E9 F1000 ; intro line\nG1 X100 E12.5 F1000 ; intro line\nG92 E0' \
        "$tmp/plate.stl"
fi
if command -v slic3r >/dev/null; then
    slic3r --print-center 100,100 --layer-height 0.2 --first-layer-height 0.3 --nozzle-diameter 0.4 --spiral-vase \
        --perimeters 1 --top-solid-layers 0 --bottom-solid-layers 2 "$tmp/star.stl" -o "$out/slic3r-vase-star.gcode" \
        >/dev/null 2>&1 || echo "slic3r failed: slic3r-vase-star.gcode"
fi
if command -v CuraEngine >/dev/null; then
    # Cura's Ender-3 start code as Cura ships it: the purge line at Z 0.28, above the 0.2 mm
    # first layer (without comments it is left downwards: no layer of its own).
    start='G28\nG92 E0\nG1 Z2.0 F3000\nG1 X0.1 Y20 Z0.28 F5000.0\nG1 X0.1 Y200.0 Z0.28 F1500.0 E15\nG1 X0.4 Y200.0 Z0.28 F5000.0\nG1 X0.4 Y20 Z0.28 F1500.0 E30\nG92 E0\nG1 Z2.0 F3000'
    cura cura-vase-star.gcode -s layer_height=0.2 -s layer_height_0=0.2 -s magic_spiralize=true -s wall_line_count=1 \
        -s top_layers=0 -s bottom_layers=2 -s adhesion_type=none -s top_bottom_pattern_0=lines -s top_bottom_pattern=lines \
        -l "$tmp/star.stl"
fi
# The BambuStudio file (; CHANGE_LAYER, M73 L, G2/G3 arc fitting) is real output fetched from a
# public repository, trimmed: see tests/fixtures/corpus/SOURCES.md.
ls -la "$out"
du -sh "$out"
