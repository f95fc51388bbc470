"""What the printcore drivers share: printcore connected to a port with the printer's lines
collected as they come (and a bounded wait for one that matches), and the end of the driver's
process whatever printcore's threads still do (its reader and sender threads are not daemons).
"""

import json
import os
import sys
import threading
import time

from printrun.printcore import printcore


class Session:
    """printcore on `port`, its received lines in `received` (stripped), the temperature
    reports among them counted in `reports`."""

    def __init__(self, port, online_s=20.0, poll_s=0.05):
        self.received = []
        self.reports = 0
        self._cond = threading.Condition()
        self.p = printcore()
        self.p.recvcb = self._on_recv
        self.p.connect(port, 115200)
        end = time.monotonic() + online_s
        while not self.p.online and time.monotonic() < end:
            time.sleep(poll_s)

    def _on_recv(self, line):
        with self._cond:
            s = line.strip()
            self.received.append(s)
            if s.startswith("T:"):
                self.reports += 1
            self._cond.notify_all()

    def mark(self):
        """Where the next received line will be (for `wait_for`)."""
        return len(self.received)

    def wait_for(self, pred, secs, start=0):
        """The first line from index `start` on that matches `pred`, within `secs`, or None."""
        end = time.monotonic() + secs
        with self._cond:
            i = start
            while True:
                while i < len(self.received):
                    if pred(self.received[i]):
                        return self.received[i]
                    i += 1
                left = end - time.monotonic()
                if left <= 0:
                    return None
                self._cond.wait(left)


    def ask(self, cmd, pred, secs):
        """Send `cmd` now (`send_now`) and wait for the first line after it matching `pred`."""
        mark = self.mark()
        self.p.send_now(cmd)
        return self.wait_for(pred, secs, mark)

    def end_marker(self, tag, secs):
        """M400, then `M118 <tag>`: whether the echo came (everything before it has run)."""
        self.p.send_now("M400")
        got = self.ask("M118 " + tag, lambda l: tag in l and not l.startswith("M118"), secs)
        return got is not None


def run(main):
    """Run `main` (returning an exit status) and end the process: a failure is reported as
    one JSON object, never a hang."""
    try:
        code = main()
    except Exception as e:  # report, never hang
        print(json.dumps({"error": repr(e)}))
        code = 3
    sys.stdout.flush()
    os._exit(code)
