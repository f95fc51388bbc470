#!/usr/bin/env python3
"""Drive Printrun's printcore (the engine under Pronterface and pronsole) against a printer on a
serial port, the way a Pronterface user does: stream a slicer file with printcore's own
streaming (`startprint`), and pause, resume and cancel through its normal send path
(`send_now`, which queues a line behind the stream's next `ok`).

Scenarios, in one session (each wait bounded):
  pause   after the stream has passed line --pause-line: send_now("M601") while printcore
          streams; at the firmware's `//action:paused` (printcore ignores it and streams on),
          send_now M105 (answered?), a jog (G91, G1 Z2, G90), then send_now("M602"); wait for
          `//action:resumed`.
  layer   the same with send_now("M761 L<--pause-layer>") at --layer-request-line.
  host_pause  printcore's own pause() at --host-pause-line (stops its stream; the firmware
          runs what it holds), then its resume().
  cancel  after the stream has passed line --cancel-line: send_now("M524"), then
          printcore's own cancelprint() once the firmware says `//action:cancel` (or after
          --wait seconds).
  end     send_now M400 and M118 drive-end; wait for the echo (every move the firmware
          accepted has run).
  repeat  (--repeat N) N more prints of the same job in the same session, each cancelled after
          the stream has passed line --m27-line, where send_now("M27") asks for the firmware's
          layer counter (printcore sends `N-1 M110` at each startprint: the count restarts).

Prints one JSON object: the events with wall-clock seconds, and what each scenario saw.
Needs only printcore (Printrun from PyPI, no GUI dependencies) and pyserial.
"""

import argparse
import json
import threading
import time

from printrun import gcoder
from printrun.printcore import printcore

from joblines import job_lines
from printcore_session import run


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--layers", type=int, default=3)
    ap.add_argument("--pause-line", type=int, default=150)
    ap.add_argument("--layer-request-line", type=int, default=0)
    ap.add_argument("--pause-layer", type=int, default=2)
    ap.add_argument("--host-pause-line", type=int, default=0)
    ap.add_argument("--cancel-line", type=int, default=0)
    ap.add_argument("--wait", type=float, default=20.0)
    ap.add_argument("--timeout", type=float, default=240.0)
    ap.add_argument("--repeat", type=int, default=0)
    ap.add_argument("--m27-line", type=int, default=400)
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

    def marker(tag, secs):
        """send_now an M400 and an M118 <tag>; wait (bounded) for the echo of the tag: every
        move the firmware accepted before has run (the M118 is taken after the M400's ok)."""
        wait_for.mark = len(received)
        p.send_now("M400")
        p.send_now("M118 " + tag)
        return wait_for(lambda l: tag in l and not l.startswith("M118"), secs) is not None

    def firmware_pause(name, request):
        """A firmware pause through printcore's normal send path while it keeps streaming
        (it ignores //action:paused): `request` (M601, or M761 L<n> for a pause at layer n)
        with send_now; once paused, a status line (M105) and a jog (G91, G1 Z2, G90) with
        send_now, then send_now("M602"). Every send_now goes out with one of the `ok`s the
        firmware's parked intake gives printcore's job lines."""
        sc = {"request": request}
        qi = wait_queue(sc_line[name])
        ev(name + "_request", queueindex=qi)
        sc["request_queueindex"] = qi
        wait_for.mark = len(received)
        p.send_now(request)
        paused = wait_for(lambda l: l.startswith("//action:paused"), a.wait)
        sc["paused"] = bool(paused)
        ev(name + ("_paused" if paused else "_pause_timeout"), queueindex=p.queueindex)
        if paused:
            sc["printcore_streaming"] = bool(p.printing)
            t = time.monotonic()
            wait_for.mark = len(received)
            p.send_now("M105")
            temp = wait_for(lambda l: l.startswith("ok T:"), a.wait)
            sc["m105_answered"] = bool(temp)
            sc["m105_s"] = round(time.monotonic() - t, 3)
            for l in ("G91", "G1 Z2 F600", "G90"):
                p.send_now(l)
            t = time.monotonic()
            wait_for.mark = len(received)
            p.send_now("M602")
            resumed = wait_for(lambda l: l.startswith("//action:resumed"), a.wait)
            sc["resumed"] = bool(resumed)
            sc["resume_s"] = round(time.monotonic() - t, 3)
            ev(name + ("_resumed" if resumed else "_resume_timeout"))
            if not resumed:
                p.printer.write(bytes([0x12]))  # do not leave the sim paused
        out["scenarios"][name] = sc

    def host_pause(name):
        """printcore's own pause() (Pronterface's Pause button): it stops streaming; the
        firmware runs what it holds and stands still (a host pause, mid-layer, no park); then
        printcore's resume() (its restore lines, then the stream)."""
        sc = {}
        qi = wait_queue(sc_line[name])
        sc["request_queueindex"] = qi
        p.pause()
        sc["paused"] = bool(p.paused and not p.printing)
        stopped_at = p.queueindex
        sc["drained"] = marker("hostpause-drained", a.wait)
        sc["stream_stopped"] = p.queueindex == stopped_at
        ev(name + "_drained", queueindex=p.queueindex)
        p.resume()
        sc["resumed"] = bool(p.printing)
        end_wait = time.monotonic() + a.wait
        while p.printing and p.queueindex <= stopped_at + 5 and time.monotonic() < end_wait:
            time.sleep(0.01)
        sc["streaming_again"] = p.queueindex > stopped_at + 5 or not p.printing
        ev(name + "_resumed", queueindex=p.queueindex)
        out["scenarios"][name] = sc

    sc_line = {
        "pause": a.pause_line,
        "layer": a.layer_request_line,
        "host_pause": a.host_pause_line,
    }
    firmware_pause("pause", "M601")
    if a.layer_request_line > 0:
        firmware_pause("layer", "M761 L%d" % a.pause_layer)
    if a.host_pause_line > 0:
        host_pause("host_pause")

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

    # Every move the firmware accepted has run once the M118 after an M400 is echoed.
    done = marker("drive-end", max(a.wait, 60.0))
    ev("m400_ok" if done else "m400_timeout")
    out["scenarios"]["end"] = {"m400_ok": bool(done)}

    # The same job printed again, a.repeat times: the layer counter at the same point of each.
    counters = []
    for k in range(a.repeat):
        while p.printing and time.monotonic() < deadline:
            time.sleep(0.05)
        p.startprint(gc)
        ev("repeat_start", n=k)
        wait_queue(a.m27_line)
        wait_for.mark = len(received)
        p.send_now("M27")
        got = wait_for(lambda l: l.startswith("echo:layer"), a.wait)
        counters.append(got)
        ev("repeat_m27", n=k, answer=got, queueindex=p.queueindex)
        wait_for.mark = len(received)
        p.send_now("M524")
        wait_for(lambda l: l.startswith("//action:cancel"), a.wait)
        p.cancelprint()
        marker("repeat-%d-end" % k, max(a.wait, 60.0))
    if a.repeat:
        out["scenarios"]["repeat"] = {"m27": counters}
    out["errors"] = [l for _, l in received if l.startswith("Error")]
    out["received_tail"] = [l for _, l in received[-15:]]
    p.disconnect()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    run(main)
