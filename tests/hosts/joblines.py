"""The part of a slicer file the host tests print (shared by the drivers)."""

import re

_Z = re.compile(r"(\sZ)(-?\d*\.?\d+)")


def job_lines(path, layers, repeat=1):
    """The file's lines up to (not including) the `layers`-th layer change marker + 1, then
    the file's last 20 lines (end code). 0 = the whole file.

    `repeat` > 1 (the whole file only): the layers are printed `repeat` times, each copy
    stacked on the one below (its G0/G1 Z words raised by the part's height), between the
    file's start code and its end code — a longer job of the same slicer's lines (an
    eight-hour pause needs ≈ 29 000 lines to stream into the parked printer at one a
    second; the fixture has ≈ 8 000)."""
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = [l.rstrip("\n") for l in f]
    if layers <= 0 or repeat > 1:
        if repeat <= 1:
            return lines
        marks = [i for i, l in enumerate(lines) if l.startswith(";LAYER_CHANGE") or l.startswith(";LAYER:")]
        first, last = marks[0], marks[-1]
        end = max(i for i in range(last, len(lines)) if lines[i].startswith(("G1", "G0", "G92")))
        body = lines[first : end + 1]
        height = max(
            float(m.group(2))
            for l in body
            if l.startswith(("G0", "G1"))
            for m in [_Z.search(l.split(";")[0])]
            if m
        )
        out = lines[:first] + body
        for k in range(1, repeat):
            dz = k * height

            def lift(l):
                if not l.startswith(("G0", "G1")):
                    return l
                code, sep, comment = l.partition(";")
                code = _Z.sub(lambda m: "%s%.3f" % (m.group(1), float(m.group(2)) + dz), code)
                return code + sep + comment

            out += [lift(l) for l in body]
        return out + lines[end + 1 :]
    seen = 0
    for i, l in enumerate(lines):
        if l.startswith(";LAYER_CHANGE") or l.startswith(";LAYER:"):
            seen += 1
            if seen > layers:
                return lines[:i] + [l for l in lines[-20:] if not l.startswith(";")]
    return lines
