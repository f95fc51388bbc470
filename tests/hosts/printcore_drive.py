#!/usr/bin/env python3
"""Drive Printrun's printcore (the engine under Pronterface and pronsole) against a printer on a
serial port, the way a Pronterface user does: stream a slicer file with printcore's own
streaming (`startprint`), and pause, resume and cancel through its normal send path
(`send_now`, which queues a line behind the stream's next `ok`).

Scenarios, in one session (each wait bounded):
  pause   after the stream has passed line --pause-line: send_now("M601"); wait for the
          firmware's `//action:paused`.
  resume  send_now("M602"); wait for `//action:resumed` (--wait seconds). If it does not come,
          the host is deadlocked behind a withheld `ok`: that is recorded and, to let the rest of
          the session run, the resume is written raw to the port (a line the firmware's
          emergency parser takes without an `ok`).
  cancel  after the stream has passed line --cancel-line: send_now("M524"), then
          printcore's own cancelprint() once the firmware says `//action:cancel` (or after
          --wait seconds).
  end     send_now("M400") and wait for its `ok` (every move the firmware accepted has run).

Prints one JSON object: the events with wall-clock seconds, and what each scenario saw.
Needs only printcore (Printrun from PyPI, no GUI dependencies) and pyserial.
"""

import argparse
import json
import os
import sys
import threading
import time

from printrun import gcoder
from printrun.printcore import printcore


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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--layers", type=int, default=3)
    ap.add_argument("--pause-line", type=int, default=150)
    ap.add_argument("--cancel-line", type=int, default=0)
    ap.add_argument("--wait", type=float, default=20.0)
    ap.add_argument("--timeout", type=float, default=240.0)
    a = ap.parse_args()

    t0 = time.monotonic()
    events = []
    received = []
    lock = threading.Lock()
    cond = threading.Condition(lock)

    def ev(name, **kw):
        kw.update(event=name, t=round(time.monotonic() - t0, 3))
        events.append(kw)

    def on_recv(line):
        with cond:
            received.append((time.monotonic() - t0, line.strip()))
            cond.notify_all()

    def wait_for(pred, secs):
        """Wait until a received line (seen from `start` on) satisfies pred; bounded."""
        end = time.monotonic() + secs
        with cond:
            start = wait_for.mark
            while True:
                for i in range(start, len(received)):
                    if pred(received[i][1]):
                        wait_for.mark = i + 1
                        return received[i][1]
                start = len(received)
                left = end - time.monotonic()
                if left <= 0:
                    return None
                cond.wait(left)

    wait_for.mark = 0

    out = {"scenarios": {}, "events": events}
    deadline = t0 + a.timeout
    p = printcore()
    p.recvcb = on_recv
    p.connect(a.port, 115200)
    end = time.monotonic() + 20
    while not p.online and time.monotonic() < end:
        time.sleep(0.05)
    ev("online", ok=bool(p.online))
    if not p.online:
        out["error"] = "printer never came online"
        print(json.dumps(out))
        return 2

    lines = job_lines(a.file, a.layers)
    gc = gcoder.LightGCode(lines)
    out["job_lines"] = len(gc)
    wait_for.mark = len(received)
    p.startprint(gc)
    ev("start")

    def wait_queue(idx):
        while p.printing and p.queueindex < idx and time.monotonic() < deadline:
            time.sleep(0.01)
        return p.queueindex

    # pause
    qi = wait_queue(a.pause_line)
    ev("pause_request", queueindex=qi)
    wait_for.mark = len(received)
    p.send_now("M601")
    paused = wait_for(lambda l: l.startswith("//action:paused"), a.wait)
    ev("paused" if paused else "pause_timeout", queueindex=p.queueindex)
    out["scenarios"]["pause"] = {"request_queueindex": qi, "paused": bool(paused)}

    # resume through the normal send path
    if paused:
        wait_for.mark = len(received)
        p.send_now("M602")
        resumed = wait_for(lambda l: l.startswith("//action:resumed"), a.wait)
        ev("resumed" if resumed else "resume_deadlock", queueindex=p.queueindex)
        sc = {"resumed_by_send_now": bool(resumed)}
        if not resumed:
            # Deadlocked behind a withheld ok: the raw line gets out (printcore's own queue
            # still holds the M602; the firmware ignores a resume when not paused).
            p.printer.write(b"M602\n")
            sc["resumed_raw"] = bool(
                wait_for(lambda l: l.startswith("//action:resumed"), a.wait)
            )
            ev("resumed_raw" if sc["resumed_raw"] else "resume_failed")
        out["scenarios"]["resume"] = sc

    # cancel
    if a.cancel_line > 0:
        qi = wait_queue(a.cancel_line)
        ev("cancel_request", queueindex=qi)
        wait_for.mark = len(received)
        p.send_now("M524")
        cancelled = wait_for(lambda l: l.startswith("//action:cancel"), a.wait)
        p.cancelprint()
        ev("cancelled" if cancelled else "cancel_timeout", queueindex=p.queueindex)
        out["scenarios"]["cancel"] = {
            "request_queueindex": qi,
            "action_cancel": bool(cancelled),
            "lines_sent": p.queueindex,
        }
    else:
        while p.printing and time.monotonic() < deadline:
            time.sleep(0.05)
        ev("stream_done", printing=p.printing, queueindex=p.queueindex)
        out["scenarios"]["stream"] = {"completed": not p.printing}

    # Every move the firmware accepted has run once M400 is answered.
    wait_for.mark = len(received)
    p.send_now("M400")
    done = wait_for(lambda l: l.startswith("ok"), max(a.wait, 60.0))
    ev("m400_ok" if done else "m400_timeout")
    out["scenarios"]["end"] = {"m400_ok": bool(done)}
    out["errors"] = [l for _, l in received if l.startswith("Error")]
    out["received_tail"] = [l for _, l in received[-15:]]
    p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    # printcore's reader and sender threads are not daemons: end the process whatever they do.
    try:
        code = main()
    except Exception as e:  # report, never hang
        print(json.dumps({"error": repr(e)}))
        code = 3
    sys.stdout.flush()
    os._exit(code)
