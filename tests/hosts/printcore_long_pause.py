#!/usr/bin/env python3
"""Printrun's printcore through a long firmware pause (issue 22): it streams a slicer file,
send_now("M601") pauses it at the layer, and while printcore keeps streaming into the parked
printer (it ignores //action:paused) console lines (M105, M114, a jog) are sent with send_now at
seeded random moments over --pause-virtual-s of virtual time (counted by the printer's
M155 temperature auto-reports); each must be answered. Then send_now("M602") and the end
marker (M400 + M118). The virtual delivery bound is the sim's record (`ports`), not measured
here: real time is no measure of virtual time under `sim serve --host-paced`.

Prints one JSON object: per console line its wall delivery time, and the rest.
"""

import argparse
import json
import random
import time

from printrun import gcoder

from joblines import job_lines
from printcore_session import Session, run


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--layers", type=int, default=99)
    ap.add_argument("--repeat", type=int, default=1, help="print the file's layers this many times, stacked")
    ap.add_argument("--pause-line", type=int, default=150)
    ap.add_argument("--speed", type=float, required=True)
    ap.add_argument("--pause-virtual-s", type=float, default=8 * 3600)
    ap.add_argument("--console-lines", type=int, default=24)
    ap.add_argument("--seed", type=int, default=22)
    ap.add_argument("--wait", type=float, default=20.0)
    ap.add_argument("--report-s", type=int, default=60)
    ap.add_argument("--wall-limit", type=float, default=240.0)
    a = ap.parse_args()
    rnd = random.Random(a.seed)
    t0 = time.monotonic()
    s = Session(a.port)
    p, received, wait_for = s.p, s.received, s.wait_for
    out = {}
    if not p.online:
        print(json.dumps({"error": "never online"}))
        return 2
    gc = gcoder.LightGCode(job_lines(a.file, a.layers, a.repeat))
    out["job_lines"] = len(gc)
    p.startprint(gc)
    while p.printing and p.queueindex < a.pause_line:
        time.sleep(0.005)
    mark = len(received)
    p.send_now("M601")
    out["paused"] = wait_for(lambda l: l.startswith("//action:paused"), a.wait, mark) is not None
    t_paused = time.monotonic()
    # Virtual time, counted by the printer's own temperature auto-reports (one per
    # --report-s virtual seconds): with `sim serve --host-paced` virtual time is not a fixed
    # multiple of real time.
    reports_wanted = int(a.pause_virtual_s / a.report_s)
    mark = s.reports
    p.send_now("M155 S%d" % a.report_s)
    moments = sorted(rnd.sample(range(2, reports_wanted - 1), a.console_lines))
    kinds = [("M105", lambda l: l.startswith("ok T:")), ("M114", lambda l: l.startswith("X:"))]
    console = []

    def reports_since(start):
        return s.reports - start

    k = 0
    deadline = time.monotonic() + a.wall_limit
    while time.monotonic() < deadline:
        n = reports_since(mark)
        if k < len(moments) and n >= moments[k]:
            cmd, pred = kinds[k % 2]
            m2 = len(received)
            t = time.monotonic()
            if k % 5 == 4:
                for l in ("G91", "G1 Z1 F600", "G1 Z-1 F600", "G90"):
                    p.send_now(l)
            p.send_now(cmd)
            got = wait_for(pred, a.wait, m2)
            console.append({"cmd": cmd, "at_virtual_s": n * a.report_s,
                            "answered": got is not None,
                            "wall_s": round(time.monotonic() - t, 4),
                            "printcore_streaming": bool(p.printing)})
            k += 1
            continue
        if n >= reports_wanted:
            break
        time.sleep(0.01)
    out["pause_virtual_s"] = reports_since(mark) * a.report_s
    out["pause_wall_s"] = round(time.monotonic() - t_paused, 1)
    out["console"] = console
    mark = len(received)
    t = time.monotonic()
    p.send_now("M602")
    out["resumed"] = wait_for(lambda l: l.startswith("//action:resumed"), a.wait, mark) is not None
    out["resume_wall_s"] = round(time.monotonic() - t, 3)
    p.send_now("M155 S0")
    end = time.monotonic() + 600
    while p.printing and time.monotonic() < end:
        time.sleep(0.05)
    # Lines the printer kept on the card run after the resume; a console M400 sent before
    # they have run would go into the spill behind them and be answered when taken (as every
    # spilled line), so printcore has streamed everything and the firmware says the card's
    # lines ran before the end marker is asked for.
    if any("kept on the SD card" in l for l in received):
        out["spill_ran"] = wait_for(lambda l: "kept on the SD card have run" in l, 600, 0) is not None
    out["end"] = s.end_marker("long-pause-end", 600)
    out["spill_notes"] = [l for l in received if "SD card" in l]
    out["errors"] = [l for l in received if l.startswith("Error")]
    out["wall_s"] = round(time.monotonic() - t0, 1)
    p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    run(main)
