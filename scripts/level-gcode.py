#!/usr/bin/env python3
"""Bake a bed-levelling plane into a G-code file as MatterControl's software levelling does
(MatterControl's LevelingStream and its tests: "; Software Leveling Applied" first, every move
cut into pieces of at most 1 mm, each piece's Z the commanded Z plus the bed's height at its end).

    scripts/level-gcode.py IN OUT [--tilt-x MM_PER_100MM] [--tilt-y MM_PER_100MM] [--offset MM]

The layer corpus uses it to make files with levelling baked in from real slicer files
(docs/testing.md, "The real-file corpus"). Moves: G0/G1 (absolute or relative XYZ, M82/M83 E,
G92); arcs and everything else pass through unchanged. Comments are kept.
"""
import argparse
import math
import re

WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("inp")
    ap.add_argument("out")
    ap.add_argument("--tilt-x", type=float, default=0.2, help="mm of bed rise per 100 mm of X")
    ap.add_argument("--tilt-y", type=float, default=-0.1, help="mm of bed rise per 100 mm of Y")
    ap.add_argument("--offset", type=float, default=0.0, help="bed height at X0 Y0, mm")
    ap.add_argument("--piece", type=float, default=1.0, help="longest piece, mm")
    a = ap.parse_args()

    def bed(x, y):
        return a.offset + a.tilt_x * x / 100.0 + a.tilt_y * y / 100.0

    pos = [0.0, 0.0, 0.0, 0.0]  # commanded X Y Z E (as written, G92 applied)
    rel_xyz = False
    rel_e = False
    out = ["; Software Leveling Applied"]
    with open(a.inp, encoding="utf-8", errors="surrogateescape") as f:
        for raw in f:
            line = raw.rstrip("\n").rstrip("\r")
            code, sep, comment = line.partition(";")
            words = WORD.findall(code)
            cmd = (words[0][0].upper() + str(int(float(words[0][1])))) if words else ""
            if cmd in ("G90",):
                rel_xyz, rel_e = False, False
            elif cmd == "G91":
                rel_xyz, rel_e = True, True
            elif cmd == "M82":
                rel_e = False
            elif cmd == "M83":
                rel_e = True
            elif cmd == "G92":
                for l, v in words[1:]:
                    k = "XYZE".find(l.upper())
                    if k >= 0:
                        pos[k] = float(v)
            elif cmd == "G28":
                named = [l.upper() for l, _ in words[1:] if l.upper() in "XYZ"]
                for k, l in enumerate("XYZ"):
                    if not named or l in named:
                        pos[k] = 0.0
            if cmd not in ("G0", "G1"):
                out.append(line)
                continue
            target = list(pos)
            feed = None
            for l, v in words[1:]:
                l = l.upper()
                k = "XYZE".find(l)
                if k >= 0:
                    rel = rel_e if k == 3 else rel_xyz
                    target[k] = pos[k] + float(v) if rel else float(v)
                elif l == "F":
                    feed = v
            dist = math.hypot(target[0] - pos[0], target[1] - pos[1])
            n = max(1, math.ceil(dist / a.piece - 1e-9))
            for i in range(1, n + 1):
                t = i / n
                p = [pos[k] + (target[k] - pos[k]) * t for k in range(4)]
                parts = [cmd]
                if dist > 0:
                    parts += ["X%.3f" % p[0], "Y%.3f" % p[1]]
                parts.append("Z%.3f" % (p[2] + bed(p[0], p[1])))
                if target[3] != pos[3]:
                    e = p[3] - (pos[3] + (target[3] - pos[3]) * (i - 1) / n) if rel_e else p[3]
                    parts.append("E%.5f" % e)
                if feed is not None and i == 1:
                    parts.append("F" + feed)
                text = " ".join(parts)
                if sep and i == n:
                    text += " ;" + comment
                out.append(text)
            pos = target
    with open(a.out, "w", encoding="utf-8", errors="surrogateescape") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
