#!/usr/bin/env python3
"""Printrun's printcore and a held job (issue 27): it streams the first layers of a slicer file
(with its heat-up and end code); send_now("M601") pauses it at --pause-line of the job (negative:
counted from the end, so that the rest of the file — the end code included — comes into the
parked printer); printcore streams on into the parked printer (it ignores //action:paused)
for --pause-virtual-s of virtual time (counted by the printer's M155 reports), longer than the
nozzle timeout; optionally a console jog (send_now G91, G1 Z1, G90) while parked; then
send_now("M602"), and an M105 sent the moment //action:resumed arrives gives the nozzle's
temperature when the held job's first extrusion runs (the resume has re-heated and waited
before it moved back). --pause-line 0: no pause (the reference run). --jobs N: the job N
times on the one connection (printcore's startprint again once it has sent the last line),
the last one paused. Then the end marker
(M400 + M118). The moves themselves are judged by the sim's move trace (`sim serve --trace`).

Prints one JSON object.
"""

import argparse
import json
import os
import re
import sys
import threading
import time

from printrun import gcoder
from printrun.printcore import printcore

from joblines import job_lines

_TEMP = re.compile(r"T:\s*(-?\d+\.?\d*)\s*/\s*(-?\d+\.?\d*)")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--layers", type=int, default=3)
    ap.add_argument("--pause-line", type=int, default=0)
    ap.add_argument("--pause-virtual-s", type=float, default=300)
    ap.add_argument("--report-s", type=int, default=10)
    ap.add_argument("--jog", action="store_true")
    ap.add_argument(
        "--jobs", type=int, default=1, help="the job this many times on one connection; the last is paused"
    )
    ap.add_argument("--wait", type=float, default=30.0)
    ap.add_argument("--wall-limit", type=float, default=240.0)
    a = ap.parse_args()
    t0 = time.monotonic()
    received = []
    cond = threading.Condition()
    reports = [0]

    def on_recv(line):
        with cond:
            received.append(line.strip())
            if line.strip().startswith("T:"):
                reports[0] += 1
            cond.notify_all()

    def wait_for(pred, secs, start):
        end = time.monotonic() + secs
        with cond:
            i = start
            while True:
                while i < len(received):
                    if pred(received[i]):
                        return received[i]
                    i += 1
                left = end - time.monotonic()
                if left <= 0:
                    return None
                cond.wait(left)

    out = {}
    p = printcore()
    p.recvcb = on_recv
    p.connect(a.port, 115200)
    end = time.monotonic() + 20
    while not p.online and time.monotonic() < end:
        time.sleep(0.05)
    if not p.online:
        print(json.dumps({"error": "never online"}))
        return 2
    lines = job_lines(a.file, a.layers)
    deadline = time.monotonic() + a.wall_limit
    # Earlier jobs on the same connection, unpaused, each to its end.
    for _ in range(a.jobs - 1):
        gc = gcoder.LightGCode(lines)
        p.startprint(gc)
        while p.printing and time.monotonic() < deadline:
            time.sleep(0.05)
    gc = gcoder.LightGCode(lines)
    out["job_lines"] = len(gc)
    p.startprint(gc)
    if a.pause_line != 0:
        at = a.pause_line if a.pause_line > 0 else len(gc) + a.pause_line
        while p.printing and p.queueindex < at:
            time.sleep(0.005)
        out["pause_sent_at_line"] = p.queueindex
        mark = len(received)
        p.send_now("M601")
        out["paused"] = wait_for(lambda l: l.startswith("//action:paused"), a.wait, mark) is not None
        mark = reports[0]
        p.send_now("M155 S%d" % a.report_s)
        wanted = int(a.pause_virtual_s / a.report_s)
        jogged = False
        while time.monotonic() < deadline and reports[0] - mark < wanted:
            if a.jog and not jogged and reports[0] - mark >= wanted // 2:
                for l in ("G91", "G1 Z1 F600", "G90"):
                    p.send_now(l)
                jogged = True
            time.sleep(0.01)
        out["pause_virtual_s"] = (reports[0] - mark) * a.report_s
        out["streamed_while_parked_to_line"] = p.queueindex
        out["nozzle_off_noted"] = any("nozzle heater off" in l for l in received)
        p.send_now("M155 S0")
        mark = len(received)
        p.send_now("M602")
        got = wait_for(lambda l: l.startswith("//action:resumed"), a.wait * 4, mark)
        out["resumed"] = got is not None
        mark = len(received)
        p.send_now("M105")
        t = wait_for(lambda l: l.startswith("ok T:") or l.startswith("T:"), a.wait, mark)
        m = _TEMP.search(t or "")
        out["nozzle_c_at_resume"] = float(m.group(1)) if m else None
        out["nozzle_target_c_at_resume"] = float(m.group(2)) if m else None
    while p.printing and time.monotonic() < deadline:
        time.sleep(0.05)
    mark = len(received)
    p.send_now("M400")
    p.send_now("M118 held-job-end")
    out["end"] = wait_for(lambda l: "held-job-end" in l and not l.startswith("M118"), 300, mark) is not None
    out["refused"] = [l for l in received if "refused" in l]
    out["errors"] = [l for l in received if l.startswith("Error")]
    out["wall_s"] = round(time.monotonic() - t0, 1)
    p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    try:
        code = main()
    except Exception as e:  # report, never hang
        print(json.dumps({"error": repr(e)}))
        code = 3
    sys.stdout.flush()
    os._exit(code)
