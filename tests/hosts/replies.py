"""What the drivers read from the printer's replies, whichever host library they drive."""

import re

_TEMP = re.compile(r"T:\s*(-?\d+\.?\d*)\s*/\s*(-?\d+\.?\d*)")


def nozzle_c(line):
    """The nozzle's temperature and target in a temperature report (`ok T:200.1 /200.0 …`),
    or (None, None)."""
    m = _TEMP.search(line or "")
    return (float(m.group(1)), float(m.group(2))) if m else (None, None)
