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
import time

from printrun import gcoder

from joblines import job_lines
from printcore_session import Session, run
from replies import nozzle_c

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
    s = Session(a.port)
    p, received, wait_for = s.p, s.received, s.wait_for
    out = {}
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
        mark = s.reports
        p.send_now("M155 S%d" % a.report_s)
        wanted = int(a.pause_virtual_s / a.report_s)
        jogged = False
        while time.monotonic() < deadline and s.reports - mark < wanted:
            if a.jog and not jogged and s.reports - mark >= wanted // 2:
                for l in ("G91", "G1 Z1 F600", "G90"):
                    p.send_now(l)
                jogged = True
            time.sleep(0.01)
        out["pause_virtual_s"] = (s.reports - mark) * a.report_s
        out["streamed_while_parked_to_line"] = p.queueindex
        out["nozzle_off_noted"] = any("nozzle heater off" in l for l in received)
        p.send_now("M155 S0")
        mark = len(received)
        p.send_now("M602")
        got = wait_for(lambda l: l.startswith("//action:resumed"), a.wait * 4, mark)
        out["resumed"] = got is not None
        t = s.ask("M105", lambda l: l.startswith("ok T:") or l.startswith("T:"), a.wait)
        out["nozzle_c_at_resume"], out["nozzle_target_c_at_resume"] = nozzle_c(t)
    while p.printing and time.monotonic() < deadline:
        time.sleep(0.05)
    out["end"] = s.end_marker("held-job-end", 300)
    out["refused"] = [l for l in received if "refused" in l]
    out["errors"] = [l for l in received if l.startswith("Error")]
    out["wall_s"] = round(time.monotonic() - t0, 1)
    p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    run(main)
