#!/usr/bin/env python3
"""Printrun's printcore (the engine under Pronterface) printing a short job on the emulated
SKR 2's USB port (`board-emu --serve`), as a Pronterface user does: printcore's own streaming
(`startprint`; it strips comments as it sends), `send_now("M601")` once the printer says (M27,
polled) it prints layer --pause-in-layer or later, the park waited for (`//action:paused`; printcore ignores it and streams on),
--park-s seconds parked, `send_now("M602")`, `//action:resumed`, the stream's end, then M400
and `M118 drive-end` (answered once every accepted move has run).

Prints one JSON object: the events with wall-clock seconds and what was seen.
"""

import argparse
import json
import sys
import threading
import time

from printrun import gcoder
from printrun.printcore import printcore


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--pause-in-layer", type=int, default=1)
    ap.add_argument("--park-s", type=float, default=2.0)
    ap.add_argument("--wait", type=float, default=120.0)
    a = ap.parse_args()

    t0 = time.monotonic()
    out = {"events": [], "errors": []}
    received = []
    cond = threading.Condition()

    def ev(name, **kw):
        kw.update(event=name, t=round(time.monotonic() - t0, 2))
        out["events"].append(kw)

    def on_recv(line):
        with cond:
            received.append(line.strip())
            cond.notify_all()

    def wait_for(pred, secs, start=0):
        end = time.monotonic() + secs
        with cond:
            while True:
                for i in range(start, len(received)):
                    if pred(received[i]):
                        return i
                left = end - time.monotonic()
                if left <= 0:
                    return None
                cond.wait(min(left, 0.2))

    lines = open(a.file).read().splitlines()
    p = printcore()
    p.recvcb = on_recv
    p.errorcb = lambda e: out["errors"].append(str(e))
    p.connect(a.port, 115200)
    end = time.monotonic() + a.wait
    while not p.online and time.monotonic() < end:
        time.sleep(0.1)
    ev("online", ok=p.online)
    if not p.online:
        print(json.dumps(out))
        return 1
    p.startprint(gcoder.LightGCode(lines))
    ev("started")
    end = time.monotonic() + a.wait
    layer = None
    while (layer is None or layer < a.pause_in_layer) and time.monotonic() < end:
        mark = len(received)
        p.send_now("M27")
        i = wait_for(lambda l: l.startswith("echo:layer "), 5, mark)
        if i is not None:
            try:
                layer = int(received[i].split()[1])
            except (IndexError, ValueError):
                pass
        time.sleep(0.3)
    mark = len(received)
    p.send_now("M601")
    ev("m601", queueindex=p.queueindex, layer=layer)
    i = wait_for(lambda l: l == "//action:paused", a.wait, mark)
    ev("paused", ok=i is not None)
    time.sleep(a.park_s)
    mark = len(received)
    p.send_now("M602")
    ev("m602")
    i = wait_for(lambda l: l == "//action:resumed", a.wait, mark)
    ev("resumed", ok=i is not None)
    end = time.monotonic() + a.wait
    while p.printing and time.monotonic() < end:
        time.sleep(0.05)
    ev("stream_done", printing=p.printing)
    mark = len(received)
    p.send_now("M400")
    p.send_now("M118 drive-end")
    i = wait_for(lambda l: "drive-end" in l, a.wait, mark)
    ev("end", ok=i is not None)
    out["actions"] = [l for l in received if l.startswith("//action:")]
    out["resends"] = sum(1 for l in received if l.startswith("Resend"))
    out["refused"] = [l for l in received if "refused" in l or l.startswith("Error")]
    out["seconds"] = round(time.monotonic() - t0, 1)
    p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
