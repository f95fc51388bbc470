#!/usr/bin/env python3
"""Printrun's printcore through a long firmware pause (issue 22): it streams a slicer file,
send_now("M601") pauses it at the layer, and while printcore keeps streaming into the parked
printer (it ignores //action:paused) console lines (M105, M114, a jog) are sent with send_now at
seeded random moments over --pause-virtual-s of virtual time; each must be answered. Then
send_now("M602") and the end marker (M400 + M118). `--speed` is the sim's, to convert.

Prints one JSON object: per console line its wall and virtual delivery time, and the rest.
"""

import argparse
import json
import os
import random
import sys
import threading
import time

from printrun import gcoder
from printrun.printcore import printcore

from joblines import job_lines


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--layers", type=int, default=99)
    ap.add_argument("--pause-line", type=int, default=150)
    ap.add_argument("--speed", type=float, required=True)
    ap.add_argument("--pause-virtual-s", type=float, default=8 * 3600)
    ap.add_argument("--console-lines", type=int, default=24)
    ap.add_argument("--seed", type=int, default=22)
    ap.add_argument("--wait", type=float, default=20.0)
    a = ap.parse_args()
    rnd = random.Random(a.seed)
    t0 = time.monotonic()
    received = []
    cond = threading.Condition()

    def on_recv(line):
        with cond:
            received.append(line.strip())
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
    gc = gcoder.LightGCode(job_lines(a.file, a.layers))
    out["job_lines"] = len(gc)
    p.startprint(gc)
    while p.printing and p.queueindex < a.pause_line:
        time.sleep(0.005)
    mark = len(received)
    p.send_now("M601")
    out["paused"] = wait_for(lambda l: l.startswith("//action:paused"), a.wait, mark) is not None
    t_paused = time.monotonic()
    pause_wall = a.pause_virtual_s / a.speed
    moments = sorted(rnd.uniform(0.02, 0.98) * pause_wall for _ in range(a.console_lines))
    kinds = [("M105", lambda l: l.startswith("ok T:")), ("M114", lambda l: l.startswith("X:"))]
    console = []
    for k, at in enumerate(moments):
        while time.monotonic() < t_paused + at:
            time.sleep(0.002)
        cmd, pred = kinds[k % 2]
        mark = len(received)
        t = time.monotonic()
        if k % 5 == 4:
            for l in ("G91", "G1 Z1 F600", "G1 Z-1 F600", "G90"):
                p.send_now(l)
        p.send_now(cmd)
        got = wait_for(pred, a.wait, mark)
        dt = time.monotonic() - t
        console.append({"cmd": cmd, "at_virtual_s": round(at * a.speed, 1),
                        "answered": got is not None, "wall_s": round(dt, 4),
                        "virtual_s": round(dt * a.speed, 3),
                        "printcore_streaming": bool(p.printing)})
    while time.monotonic() < t_paused + pause_wall:
        time.sleep(0.01)
    out["console"] = console
    mark = len(received)
    t = time.monotonic()
    p.send_now("M602")
    out["resumed"] = wait_for(lambda l: l.startswith("//action:resumed"), a.wait, mark) is not None
    out["resume_virtual_s"] = round((time.monotonic() - t) * a.speed, 3)
    end = time.monotonic() + 600
    while p.printing and time.monotonic() < end:
        time.sleep(0.05)
    mark = len(received)
    p.send_now("M400")
    p.send_now("M118 long-pause-end")
    out["end"] = wait_for(lambda l: "long-pause-end" in l and not l.startswith("M118"), 600, mark) is not None
    out["spill_notes"] = [l for l in received if "SD card" in l]
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
