"""The part of a slicer file the host tests print (shared by the drivers)."""


def job_lines(path, layers):
    """The file's lines up to (not including) the `layers`-th layer change marker + 1, then
    the file's last 20 lines (end code). 0 = the whole file."""
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = [l.rstrip("\n") for l in f]
    if layers <= 0:
        return lines
    seen = 0
    for i, l in enumerate(lines):
        if l.startswith(";LAYER_CHANGE") or l.startswith(";LAYER:"):
            seen += 1
            if seen > layers:
                return lines[:i] + [l for l in lines[-20:] if not l.startswith(";")]
    return lines
