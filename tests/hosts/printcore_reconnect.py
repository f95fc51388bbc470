#!/usr/bin/env python3
"""Printrun's printcore leaving a paused printer and another printcore coming (issue 22): the
first streams a slicer file and pauses it with send_now("M601"); once //action:paused came it
disconnects (closing the port: a session ending, as DTR dropping on the board's USB port).
A second printcore connects: what does it see first, what do M602 and M524 do? Then it prints
a short job to the end (the printer is usable again).

Prints one JSON object with what the second host saw.
"""

import argparse
import json
import time

from printrun import gcoder

from joblines import job_lines
from printcore_session import Session, run


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--layers", type=int, default=6)
    ap.add_argument("--pause-line", type=int, default=150)
    ap.add_argument("--wait", type=float, default=20.0)
    a = ap.parse_args()
    out = {}
    first = Session(a.port, poll_s=0.02)
    if not first.p.online:
        print(json.dumps({"error": "first host never online"}))
        return 2
    job = job_lines(a.file, a.layers)
    first.p.startprint(gcoder.LightGCode(job))
    while first.p.printing and first.p.queueindex < a.pause_line:
        time.sleep(0.005)
    out["paused"] = first.ask("M601", lambda l: l == "//action:paused", a.wait) is not None
    first.p.disconnect()
    time.sleep(0.5)

    second = Session(a.port, poll_s=0.02)
    out["second_online"] = second.p.online
    # What a host coming to a paused printer sees first (before its own lines' answers).
    told = second.wait_for(lambda l: "paused: job held" in l, a.wait)
    out["told"] = told
    out["told_paused_action"] = second.wait_for(lambda l: l == "//action:paused", a.wait) is not None
    out["m602"] = second.ask("M602", lambda l: "resume" in l, a.wait)
    out["m114_after_m602"] = second.ask("M114", lambda l: l.startswith("X:"), a.wait)
    out["cancelled"] = second.ask("M524", lambda l: l == "//action:cancel", a.wait) is not None
    out["m114_after_cancel"] = second.ask("M400", lambda l: l.startswith("ok"), a.wait) and \
        second.ask("M114", lambda l: l.startswith("X:"), a.wait)
    # The printer is usable again: a short job to its end.
    second.p.startprint(gcoder.LightGCode(job_lines(a.file, 2)))
    end = time.monotonic() + 300
    while second.p.printing and time.monotonic() < end:
        time.sleep(0.05)
    out["second_job_sent"] = not second.p.printing
    out["end"] = second.end_marker("reconnect-end", 300)
    out["errors"] = [l for l in second.received if l.startswith("Error")]
    out["second_first_lines"] = second.received[:6]
    # Leave once the printer has run everything (a host leaving while moves are queued
    # leaves during its job: the firmware would park the head).
    time.sleep(1.0)
    second.p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    run(main)
