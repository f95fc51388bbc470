#!/usr/bin/env python3
"""Printrun's printcore on the TFT port while OctoPrint prints on the USB port (issue 22; the
OctoPrint side is tests/hosts/octoprint_drive.py --sessions). printcore prints nothing: it
asks (M118, M27), pauses the job OctoPrint streams (M601), waits for OctoPrint's Resume, then
for OctoPrint's Pause, resumes it (M602), and waits for OctoPrint's Cancel — all seen through
the notifications on its own port.

Prints one JSON object with what it saw.
"""

import argparse
import json
import time

from printcore_session import Session, run


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--wait", type=float, default=120.0)
    a = ap.parse_args()
    s = Session(a.port, poll_s=0.02)
    p, received, wait_for = s.p, s.received, s.wait_for
    out = {}
    out["online"] = p.online
    online_mark = len(received)
    out["reply_here"] = s.ask("M118 tft-asks", lambda l: "tft-asks" in l, 20)
    # Until the job OctoPrint streams prints its third layer (M27: the firmware's layer).
    def at_layer_2(l):
        w = l.split()
        return "state printing" in l and len(w) > 1 and w[0].endswith("layer") and w[1].isdigit() and int(w[1]) >= 2

    end = time.monotonic() + a.wait
    out["printing_seen"] = False
    while time.monotonic() < end:
        l = s.ask("M27", at_layer_2, 2)
        if l is not None:
            out["printing_seen"] = l
            break
        time.sleep(0.5)
    out["paused_by_me"] = s.ask("M601", lambda l: l == "//action:paused", a.wait) is not None
    mark = len(received)
    out["resumed_by_other"] = wait_for(lambda l: l == "//action:resumed", a.wait, mark) is not None
    mark = len(received)
    out["paused_by_other"] = wait_for(lambda l: l == "//action:paused", a.wait, mark) is not None
    time.sleep(1)
    out["resumed_by_me"] = s.ask("M602", lambda l: l == "//action:resumed", a.wait) is not None
    mark = len(received)
    out["cancel_seen"] = wait_for(lambda l: l == "//action:cancel", a.wait, mark) is not None
    after = received[online_mark:]
    # Answers to OctoPrint's lines must not come here: its M105 polling's `ok T:`.
    out["others_temperature_answers"] = sum(1 for l in after if l.startswith("ok T:"))
    out["actions"] = [l for l in after if l.startswith("//action:")]
    out["errors"] = [l for l in after if l.startswith("Error")]
    p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    run(main)
