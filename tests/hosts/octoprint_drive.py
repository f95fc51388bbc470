#!/usr/bin/env python3
"""Drive a real OctoPrint (installed by scripts/setup-hosts.sh) against a printer on a serial
port, through its REST API only, as a user's browser would.

One OctoPrint session covers several scenarios (each wait bounded):
  heatup    print a slicer file; while the firmware waits in M109/M190, record the tool0/bed
            temperatures OctoPrint shows (GET /api/printer).
  button    OctoPrint's Pause button (POST /api/job pause/pause) → state "Paused" (with the
            LayerPause plugin: the firmware's layer pause, //action:paused), then its Resume
            button → "Printing".
  terminal  M601 from OctoPrint's terminal (POST /api/printer/command) → "Paused"; M602 →
            "Printing".
  m25       M25 from the terminal → "Paused"; M24 → "Printing".
  layer     pause at layer N: the plugin's API (M761 L<n>) → "Paused", N two layers above the
            one the plugin's counter (M27) shows; the counter when paused (N - 1: the last layer
            printed); resume with the button.
  cancel    OctoPrint's Cancel button → "Operational".
  reprint   (--reprint) the same file printed again in the same session (OctoPrint sends
            M110 N0 at the start of every print): pause at the same layer N, scheduled during
            the heat-up; the counter when paused; resume, cancel. With --reprint-file the
            second print is that file (e.g. one with `M73 L` markers, which stay when
            OctoPrint strips the comments).

With --sessions (another host on the TFT port, tests/hosts/printcore_tft.py) instead:
  twohosts  print; the other host pauses (state "Paused" seen here), OctoPrint's Resume
            button; OctoPrint's Pause button, the other host resumes (state "Printing" seen
            here); Cancel. OctoPrint's serial log is kept to show what reached this port.
  reconnect print again; Pause button → "Paused"; for --pause-virtual-s seconds of the
            printer's time (counted by its M155 auto-reports) the terminal's M105, M114, M27
            and jogs, --console-lines of them spread evenly (each must be answered);
            disconnect and connect again (a new session: OctoPrint has no job now); terminal
            M602 (refused by the firmware: the held job's host went away) then M524 (cancels
            it, the head stays parked).
With --held instead (issue 27, the held job):
  held      print; Pause button (the plugin: the firmware's layer pause) → "Paused"; for
            --pause-virtual-s seconds of the printer's time (counted by its M155 reports),
            longer than the nozzle timeout, nothing else; Resume button → "Printing"; an M105
            from the terminal the moment //action:resumed arrives (the nozzle when the held
            job's first extrusion runs: the resume re-heats and waits before it moves back);
            the print runs to its end ("Operational"). The moves are judged by the sim's trace.
With --stock instead (the plugin disabled, STOCK_SERIAL and STOCK_SCRIPTS set):
  stock_button    print; Pause button → "Paused", M114 (parked?); Resume button → "Printing".
  stock_terminal  terminal M601 → "Paused" (OctoPrint follows //action:paused), M114;
                  Resume button (its beforePrintResumed script: M602) → "Printing".
  stock_cancel    M114 while printing; Cancel button → "Operational"; M400 + M114.

OctoPrint runs bound to 127.0.0.1 on a free port with a temporary basedir: the first-run
wizard is marked done, every plugin that would reach the network is disabled, and a user with
an API key is written to users.yaml. Prints one JSON object with what each scenario saw.
"""

import argparse
import json
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import time

import requests
import yaml

from joblines import job_lines
from replies import nozzle_c

API_KEY = "LAYERPAUSETESTKEY0123456789ABCDEF"


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


# The settings of a stock OctoPrint (no plugin) that make its buttons use the firmware's pause
# and cancel (docs/hosts.md, "Without the plugin: settings only"): its Pause button runs
# afterPrintPaused after it stopped streaming, its Resume button beforePrintResumed, its Cancel
# button afterPrintCancelled (before its default lines: the firmware's cancel parks the head
# first, the rest runs from there).
STOCK_SERIAL = {
    "emergencyCommands": ["M112", "M108", "M410", "M601", "M602", "M25", "M24", "M524"],
    "pausingCommands": ["M0", "M1"],
}
STOCK_SCRIPTS = {
    "afterPrintPaused": "M601\n",
    "beforePrintResumed": "M602\n",
    "afterPrintCancelled": "M524\n; disable motors\nM84\n\n;disable all heaters\n"
    "{% snippet 'disable_hotends' %}\n{% snippet 'disable_bed' %}\n;disable fan\nM106 S0\n",
}


def write_basedir(base, emergency, serial_log=False, stock=False):
    config = {
        "server": {
            "firstRun": False,
            "onlineCheck": {"enabled": False},
            "pluginBlacklist": {"enabled": False},
            "allowFraming": False,
        },
        "accessControl": {"autologinLocal": False},
        "serial": {
            "additionalPorts": ["/dev/pts/*", "/proc/*/fd/*"],
            "autoconnect": False,
            # The firmware answers M105 at once; keep OctoPrint's polling at its default.
            "log": serial_log,
        },
        "plugins": {
            # Nothing that talks to the network.
            "_disabled": [
                "announcements",
                "softwareupdate",
                "tracking",
                "discovery",
                "errortracking",
                "pluginmanager",
                "pi_support",
                "firmware_check",
                "achievements",
                "virtual_printer",
                "healthcheck",
            ],
            "layerpause": {"emergency_commands": emergency},
        },
        "temperature": {"cutoff": 30},
    }
    if stock:
        config["plugins"]["_disabled"].append("layerpause")
        del config["plugins"]["layerpause"]
        config["serial"].update(STOCK_SERIAL)
        os.makedirs(os.path.join(base, "scripts", "gcode"), exist_ok=True)
        for name, text in STOCK_SCRIPTS.items():
            with open(os.path.join(base, "scripts", "gcode", name), "w") as f:
                f.write(text)
    with open(os.path.join(base, "config.yaml"), "w") as f:
        yaml.safe_dump(config, f)
    users = {
        "_version": 2,
        "tester": {
            "password": "not-a-password-hash",
            "active": True,
            "groups": ["admins", "users"],
            "permissions": [],
            "apikey": API_KEY,
            "settings": {},
        },
    }
    with open(os.path.join(base, "users.yaml"), "w") as f:
        yaml.safe_dump(users, f)


class Octo:
    def __init__(self, url):
        self.url = url
        self.s = requests.Session()
        self.s.headers["X-Api-Key"] = API_KEY

    def get(self, path):
        r = self.s.get(self.url + path, timeout=10)
        r.raise_for_status()
        return r.json()

    def post(self, path, body):
        r = self.s.post(self.url + path, json=body, timeout=10)
        if r.status_code >= 400:
            raise RuntimeError(f"POST {path} {body}: {r.status_code} {r.text[:200]}")
        return r.json() if r.content else None

    def state(self):
        return self.get("/api/job").get("state", "")

    def wait_state(self, pred, secs):
        end = time.monotonic() + secs
        st = None
        while time.monotonic() < end:
            st = self.state()
            if pred(st):
                return st, True
            time.sleep(0.1)
        return st, False


class Done(Exception):
    pass


class SerialLog:
    """OctoPrint's serial log, read on from where the last read ended (an 8-hour pause makes it
    megabytes). OctoPrint starts a new file when it connects again: its lines are appended to
    the ones read before, so positions (`mark`s) stay valid across a reconnect."""

    def __init__(self, path):
        self.path = path
        self.ino = None
        self.offset = 0
        self.partial = b""
        self.lines = []

    def read(self):
        try:
            ino = os.stat(self.path).st_ino
            with open(self.path, "rb") as f:
                if ino != self.ino:
                    self.ino, self.offset, self.partial = ino, 0, b""
                f.seek(self.offset)
                data = f.read()
        except OSError:
            return self.lines
        self.offset += len(data)
        *complete, self.partial = (self.partial + data).split(b"\n")
        for raw in complete:
            l = raw.decode(errors="replace")
            for tag in ("Recv: ", "Send: "):
                i = l.find(tag)
                if i >= 0:
                    self.lines.append((tag[:4], l[i + len(tag):].rstrip("\r")))
        return self.lines


SERIAL_LOGS = {}


def serial_lines(base):
    """OctoPrint's serial log: (direction, text) per line, Recv/Send."""
    log = SERIAL_LOGS.setdefault(base, SerialLog(os.path.join(base, "logs", "serial.log")))
    return log.read()


# --sessions: the period of the temperature auto-reports that count the pause's virtual
# seconds (M155 S<n>), virtual s.
REPORT_S = 10


def recv_since(base, mark):
    return [t for d, t in serial_lines(base)[mark:] if d == "Recv"]


def wait_recv(base, mark, pred, secs):
    """The first line OctoPrint received since `mark` that matches, within `secs` (bounded)."""
    end = time.monotonic() + secs
    while True:
        for t in recv_since(base, mark):
            if pred(t):
                return t
        if time.monotonic() > end:
            return None
        time.sleep(0.1)


def m114(o, base, terminal, wait):
    """M400 then M114 from the terminal: the answer (`X:… Y:… Z:… E:…`), or None."""
    mark = len(serial_lines(base))
    terminal("M400")()
    terminal("M114")()
    return wait_recv(base, mark, lambda t: t.startswith("X:"), wait)


def two_hosts(o, a, out, printing_on, job_cmd, base):
    """printcore on the TFT port pauses and resumes OctoPrint's job; OctoPrint's buttons are
    seen there (see the module documentation)."""
    sc = {}
    # The other host (TFT) pauses: OctoPrint sees it (the plugin follows //action:paused).
    st, ok = o.wait_state(lambda s: s == "Paused", 90)
    sc["paused_by_other"] = ok
    job_cmd("resume")()
    st, ok = o.wait_state(lambda s: s == "Printing", a.wait)
    sc["resumed_here"] = ok
    sc["printing_on_2"] = printing_on(60)
    job_cmd("pause")()
    st, ok = o.wait_state(lambda s: s == "Paused", a.wait)
    sc["paused_here"] = ok
    # The other host resumes.
    st, ok = o.wait_state(lambda s: s == "Printing", 90)
    sc["resumed_by_other"] = ok
    sc["printing_on_3"] = printing_on(60)
    o.post("/api/job", {"command": "cancel"})
    st, ok = o.wait_state(lambda s: s.startswith("Operational"), a.wait)
    sc["operational_after_cancel"] = ok
    time.sleep(1)
    recv = [t for d, t in serial_lines(base) if d == "Recv"]
    sc["recv_lines"] = len(recv)
    sc["recv_other_hosts_reply"] = [t for t in recv if "tft-asks" in t]
    sc["recv_actions"] = [t for t in recv if t.startswith("//action:")]
    out["scenarios"]["twohosts"] = sc


def long_pause_reconnect(o, a, out, printing_on, job_cmd, terminal, base):
    """Pause with the button; for --pause-virtual-s seconds the terminal's M105, M114, M27 and
    jogs (the printhead API) go to the parked printer, each answered (the sim's record judges
    the virtual delays); then disconnect and connect again: the firmware tells the new session
    the job is held, M602 is refused, M524 cancels with the head parked."""
    sc = {}
    # Pause once it prints past its start code and heat-up (at --speed 100 the whole job
    # streams in about 15 s): the firmware stops at the next layer boundary.
    end = time.monotonic() + a.wait
    sc["printing_on"] = False
    while time.monotonic() < end and not sc["printing_on"]:
        job = o.get("/api/job")
        pos = (job.get("progress") or {}).get("filepos") or 0
        sc["printing_on"] = job.get("state") == "Printing" and pos > 5000
        time.sleep(0.05)
    job_cmd("pause")()
    st, ok = o.wait_state(lambda s: s == "Paused", a.wait)
    sc["paused"] = ok
    # Virtual time, counted by the printer's own temperature auto-reports (one per
    # REPORT_S virtual seconds): with `sim serve --host-paced` virtual time is no fixed
    # multiple of real time. The terminal lines are spread evenly over --pause-virtual-s.
    terminal("M155 S%d" % REPORT_S)()
    log = serial_lines(base)
    mark = len(log)
    wanted = int(a.pause_virtual_s / REPORT_S)
    moments = [(i + 1) * wanted // (a.console_lines + 1) for i in range(a.console_lines)]
    kinds = [
        ("M105", lambda t: t.startswith("ok T:")),
        ("M114", lambda t: t.startswith("X:")),
        ("M27", lambda t: "state paused" in t),
        ("jog", lambda t: t == "ok"),
    ]
    console = []
    reports, seen = 0, mark
    t_paused = time.monotonic()
    deadline = t_paused + a.pause_wall
    while time.monotonic() < deadline:
        log = serial_lines(base)
        reports += sum(1 for d, t in log[seen:] if d == "Recv" and t.lstrip().startswith("T:"))
        seen = len(log)
        k = len(console)
        if k < len(moments) and reports >= moments[k]:
            name, pred = kinds[k % len(kinds)]
            m2 = len(log)
            if name == "jog":
                z = 1 if (k // len(kinds)) % 2 == 0 else -1
                o.post("/api/printer/printhead", {"command": "jog", "z": z})
            else:
                terminal(name)()
            got = wait_recv(base, m2, pred, a.wait)
            console.append({"cmd": name, "at_virtual_s": reports * REPORT_S,
                            "answered": got is not None})
            continue
        if reports >= wanted:
            break
        time.sleep(0.1)
    sc["pause_virtual_s"] = reports * REPORT_S
    sc["pause_wall_s"] = round(time.monotonic() - t_paused, 1)
    sc["console"] = console
    sc["state_before_disconnect"] = o.state()
    o.post("/api/connection", {"command": "disconnect"})
    st, ok = o.wait_state(lambda s: s.startswith("Offline") or s.startswith("Closed"), a.wait)
    sc["disconnected"] = ok
    sc["state_disconnected"] = st
    mark = len(serial_lines(base))
    o.post("/api/connection", {"command": "connect", "port": a.port, "baudrate": 115200})
    st, ok = o.wait_state(lambda s: s.startswith("Operational"), 30)
    sc["reconnected_state"] = st
    told = wait_recv(base, mark, lambda t: "paused: job held" in t, a.wait)
    sc["told"] = [told] if told else []
    if not told:
        sc["recv_after_connect"] = recv_since(base, mark)[:12]
    mark = len(serial_lines(base))
    terminal("M602")()
    got = wait_recv(base, mark, lambda t: "resume" in t, a.wait)
    sc["m602"] = [got] if got else []
    mark = len(serial_lines(base))
    terminal("M524")()
    sc["cancel_action"] = wait_recv(base, mark, lambda t: t == "//action:cancel", a.wait) is not None
    # The head after the cancel (after its park).
    sc["m114_after_cancel"] = m114(o, base, terminal, a.wait)
    sc["state_end"] = o.state()
    out["scenarios"]["reconnect"] = sc


def stock(o, a, out, job_cmd, terminal, base):
    """OctoPrint without the plugin, with STOCK_SERIAL and STOCK_SCRIPTS: its Pause button,
    the terminal's M601, its Resume button, its Cancel button (see docs/hosts.md)."""

    def printing_on(secs):
        end = time.monotonic() + secs
        start = None
        while time.monotonic() < end:
            job = o.get("/api/job")
            pos = (job.get("progress") or {}).get("filepos") or 0
            start = pos if start is None else start
            if job.get("state") == "Printing" and pos > start + 500:
                return True
            time.sleep(0.1)
        return False

    def pause_resume(name, pause):
        sc = {"printing_on": printing_on(60)}
        t = time.monotonic()
        pause()
        st, ok = o.wait_state(lambda s: s == "Paused", a.wait)
        sc["paused"] = ok
        sc["state_after_pause"] = st
        sc["pause_s"] = round(time.monotonic() - t, 2)
        # Parked? (the firmware's park lifts the head off the part.)
        time.sleep(1)
        mark = len(serial_lines(base))
        terminal("M114")()
        sc["m114_paused"] = wait_recv(base, mark, lambda t: t.startswith("X:"), a.wait)
        sc["actions"] = [t for t in recv_since(base, 0) if t.startswith("//action:")]
        mark = len(serial_lines(base))
        job_cmd("resume")()
        st, ok = o.wait_state(lambda s: s == "Printing", a.wait)
        sc["resumed"] = ok
        sc["state_after_resume"] = st
        # Back at the job: the resume re-heats a nozzle the pause's timeout turned off and
        # waits before the head moves; a pause asked for meanwhile is deferred until the
        # resume completes (not the next scenario's "first boundary after the request").
        sc["resumed_action"] = (
            wait_recv(base, mark, lambda t: t.startswith("//action:resumed"), a.wait * 3)
            is not None
        )
        out["scenarios"][name] = sc

    pause_resume("stock_button", job_cmd("pause"))
    if o.state() == "Printing":
        pause_resume("stock_terminal", terminal("M601"))
    sc = {"printing_on": printing_on(60)}
    mark = len(serial_lines(base))
    terminal("M114")()
    sc["m114_before"] = wait_recv(base, mark, lambda t: t.startswith("X:"), a.wait)
    o.post("/api/job", {"command": "cancel"})
    st, ok = o.wait_state(lambda s: s.startswith("Operational"), a.wait)
    sc["operational_after_cancel"] = ok
    sc["m114_after_cancel"] = m114(o, base, terminal, a.wait)
    sc["cancel_action"] = any(t == "//action:cancel" for t in recv_since(base, mark))
    out["scenarios"]["stock_cancel"] = sc


def held(o, a, out, printing_on, job_cmd, terminal, base):
    """A pause past the nozzle timeout with the plugin, then the job to its end (see the
    module documentation)."""
    sc = {}
    sc["printing_on"] = printing_on(a.wait * 3)
    job_cmd("pause")()
    st, ok = o.wait_state(lambda s: s == "Paused", a.wait * 3)
    sc["paused"] = ok
    terminal("M155 S%d" % REPORT_S)()
    mark = len(serial_lines(base))
    wanted = int(a.pause_virtual_s / REPORT_S)
    reports = 0
    deadline = time.monotonic() + a.pause_wall
    while time.monotonic() < deadline and reports < wanted:
        log = serial_lines(base)
        reports = sum(1 for d, t in log[mark:] if d == "Recv" and t.lstrip().startswith("T:"))
        time.sleep(0.1)
    sc["pause_virtual_s"] = reports * REPORT_S
    recv = recv_since(base, 0)
    sc["nozzle_off_noted"] = any("nozzle heater off" in t for t in recv)
    terminal("M155 S0")()
    mark = len(serial_lines(base))
    job_cmd("resume")()
    got = wait_recv(base, mark, lambda t: t.startswith("//action:resumed"), a.wait * 6)
    sc["resumed"] = got is not None
    mark = len(serial_lines(base))
    terminal("M105")()
    t = wait_recv(base, mark, lambda t: t.startswith("ok T:") or t.startswith("T:"), a.wait)
    sc["nozzle_c_at_resume"], sc["nozzle_target_c_at_resume"] = nozzle_c(t)
    # The print ran to its end (as printcore's drivers' end marker says for theirs).
    st, ok = o.wait_state(lambda s: s.startswith("Operational"), a.pause_wall)
    sc["end"] = ok
    sc["state_end"] = st
    recv = recv_since(base, 0)
    sc["refused"] = [t for t in recv if "refused" in t]
    sc["errors"] = [t for t in recv if t.startswith("Error")]
    out["scenarios"]["held"] = sc


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--octoprint", required=True, help="the octoprint executable")
    ap.add_argument("--layers", type=int, default=5)
    ap.add_argument("--pause-layer", type=int, default=3)
    ap.add_argument("--wait", type=float, default=20.0)
    ap.add_argument("--no-emergency", action="store_true")
    ap.add_argument("--reprint", action="store_true")
    ap.add_argument(
        "--reprint-file",
        help="with --reprint: print this file (its first --layers layers) the second time",
    )
    ap.add_argument(
        "--sessions",
        action="store_true",
        help="two hosts (printcore on the TFT port), then a long pause and a reconnect",
    )
    ap.add_argument(
        "--pause-virtual-s", type=float, default=900, help="--sessions: virtual seconds paused"
    )
    ap.add_argument(
        "--pause-wall", type=float, default=120, help="--sessions: at most this long paused, s"
    )
    ap.add_argument(
        "--console-lines", type=int, default=12, help="--sessions: terminal lines over the pause"
    )
    ap.add_argument("--stock", action="store_true", help="without the plugin (STOCK_* settings)")
    ap.add_argument(
        "--held", action="store_true", help="a pause past the nozzle timeout, then to the end"
    )
    a = ap.parse_args()

    t0 = time.monotonic()
    out = {"scenarios": {}}
    base = tempfile.mkdtemp(prefix="octoprint-test-")
    write_basedir(
        base, not a.no_emergency, serial_log=a.sessions or a.stock or a.held, stock=a.stock
    )
    port = free_port()
    log = open(os.path.join(base, "serve.log"), "w")
    proc = subprocess.Popen(
        [a.octoprint, "serve", "--iknowwhatimdoing", "--basedir", base, "--host", "127.0.0.1", "--port", str(port)],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    o = Octo(f"http://127.0.0.1:{port}")
    try:
        # Up?
        end = time.monotonic() + 90
        while True:
            try:
                out["version"] = o.get("/api/version")
                break
            except Exception:
                if time.monotonic() > end or proc.poll() is not None:
                    raise RuntimeError("OctoPrint did not come up")
                time.sleep(0.3)
        out["startup_s"] = round(time.monotonic() - t0, 1)

        o.post("/api/connection", {"command": "connect", "port": a.port, "baudrate": 115200})
        st, ok = o.wait_state(lambda s: s.startswith("Operational"), 30)
        out["connected"] = ok
        if not ok:
            raise RuntimeError(f"not operational: {st}")
        # OctoPrint turns Operational when its hello is answered; the M115 capability lines
        # that make the plugin active may be parsed a moment later, so wait for them (bounded).
        end = time.monotonic() + 15
        while not a.stock:
            try:
                out["plugin"] = o.get("/api/plugin/layerpause")
            except Exception as e:
                out["plugin"] = {"error": repr(e)}
            if out["plugin"].get("active") or time.monotonic() > end:
                break
            time.sleep(0.2)

        # The job: the file's first --layers layers plus its end code.
        text = "\n".join(job_lines(a.file, a.layers)) + "\n"

        def start_print():
            r = o.s.post(
                o.url + "/api/files/local",
                files={"file": ("job.gcode", text.encode())},
                data={"select": "true", "print": "true"},
                timeout=30,
            )
            r.raise_for_status()

        def job_cmd(action):
            return lambda: o.post("/api/job", {"command": "pause", "action": action})

        def terminal(cmd):
            return lambda: o.post("/api/printer/command", {"commands": [cmd]})

        start_print()
        if a.stock:
            stock(o, a, out, job_cmd, terminal, base)
            raise Done()

        # heatup: temperatures shown while the firmware waits in M109/M190.
        temps = []
        end = time.monotonic() + (0 if a.sessions or a.held else 60)
        while time.monotonic() < end:
            p = o.get("/api/printer?exclude=sd")
            t = p.get("temperature", {})
            tool = t.get("tool0", {})
            temps.append(
                (round(time.monotonic() - t0, 2), tool.get("actual"), tool.get("target"))
            )
            job = o.get("/api/job")
            # Heat-up over once the job has gone past the start code's waits.
            if (job.get("progress", {}).get("filepos") or 0) > 2000:
                break
            time.sleep(0.25)
        actual = [x[1] for x in temps if x[1] is not None]
        if not a.sessions:
            out["scenarios"]["heatup"] = {
            "samples": len(temps),
            "distinct_tool0": len(set(actual)),
            "max_tool0": max(actual) if actual else None,
            "first": temps[:3],
            "last": temps[-3:],
        }

        def printing_on(secs):
            """True once the plugin's state is `printing` and OctoPrint's file position has
            moved on by a few lines since this call; bounded."""
            end = time.monotonic() + secs
            start = None
            while time.monotonic() < end:
                pos = (o.get("/api/job").get("progress") or {}).get("filepos") or 0
                start = pos if start is None else start
                if o.get("/api/plugin/layerpause").get("state") == "printing" and pos > start + 500:
                    return True
                time.sleep(0.1)
            return False

        def pause_resume(name, pause, resume, wait_layer=None):
            sc = {}
            t = time.monotonic()
            pause()
            st, ok = o.wait_state(lambda s: s == "Paused", a.wait)
            sc["paused"] = ok
            sc["state_after_pause"] = st
            sc["pause_s"] = round(time.monotonic() - t, 2)
            try:
                sc["plugin"] = o.get("/api/plugin/layerpause")
            except Exception as e:
                sc["plugin"] = repr(e)
            if not ok:
                # Where did it end up? (Pausing for ever = an ok never came.)
                time.sleep(1)
                sc["state_later"] = o.state()
            resume()
            st, ok = o.wait_state(lambda s: s == "Printing", a.wait)
            sc["resumed"] = ok
            sc["state_after_resume"] = st
            # Before the next scenario: the firmware is back at the job (the plugin saw
            # //action:resumed) and OctoPrint streams again (bounded wait for that condition).
            sc["printing_on"] = printing_on(a.wait)
            out["scenarios"][name] = sc
            return sc

        if a.held:
            held(o, a, out, printing_on, job_cmd, terminal, base)
            raise Done()
        if a.sessions:
            two_hosts(o, a, out, printing_on, job_cmd, base)
            start_print()
            long_pause_reconnect(o, a, out, printing_on, job_cmd, terminal, base)
            raise Done()
        pause_resume("button", job_cmd("pause"), job_cmd("resume"))
        if o.state() == "Printing":
            pause_resume("terminal", terminal("M601"), terminal("M602"))
        if o.state() == "Printing":
            pause_resume("m25", terminal("M25"), terminal("M24"))
        def counter(secs):
            """The plugin's layer counter from a fresh M27 (bounded wait for its answer)."""
            seen = o.get("/api/plugin/layerpause").get("layer_reports", 0)
            end = time.monotonic() + secs
            while time.monotonic() < end:
                o.post("/api/plugin/layerpause", {"command": "refresh"})
                t = time.monotonic() + 2.0
                while time.monotonic() < t:
                    st = o.get("/api/plugin/layerpause")
                    if st.get("layer_reports", 0) > seen:
                        return st.get("layer")
                    time.sleep(0.1)
            return None

        pause_layer = None
        if o.state() == "Printing":
            now = counter(a.wait)
            pause_layer = now + 2 if now is not None else a.pause_layer
            got = {}

            def at_layer():
                o.post(
                    "/api/plugin/layerpause",
                    {"command": "pause_at_layer", "layer": pause_layer},
                )

            def resume_after_counter():
                # While paused: the counter M27 reports (the last layer printed).
                if o.state() == "Paused":
                    got["layer"] = counter(a.wait)
                o.post("/api/job", {"command": "pause", "action": "resume"})

            sc = pause_resume("layer", at_layer, resume_after_counter)
            sc["pause_layer"] = pause_layer
            sc["printing_layer"] = now
            sc["layer_when_paused"] = got.get("layer")

        # cancel
        sc = {}
        o.post("/api/job", {"command": "cancel"})
        st, ok = o.wait_state(lambda s: s.startswith("Operational"), a.wait)
        sc["operational_after_cancel"] = ok
        sc["state"] = st
        out["scenarios"]["cancel"] = sc

        if a.reprint and pause_layer is not None and ok:
            # The same file again, in the same session: the firmware's count restarts at
            # OctoPrint's M110 N0, and the same number is the same layer.
            sc = {"pause_layer": pause_layer}
            name = "job.gcode"
            if a.reprint_file:
                # Another file: upload it and print it.
                name = "job2.gcode"
                text = "\n".join(job_lines(a.reprint_file, a.layers)) + "\n"
                r = o.s.post(
                    o.url + "/api/files/local",
                    files={"file": (name, text.encode())},
                    data={"select": "false", "print": "false"},
                    timeout=30,
                )
                r.raise_for_status()
                sc["file"] = a.reprint_file
            o.post("/api/files/local/" + name, {"command": "select", "print": True})
            st, started = o.wait_state(lambda s: s in ("Printing", "Starting"), a.wait)
            sc["started"] = started
            o.post("/api/plugin/layerpause", {"command": "pause_at_layer", "layer": pause_layer})
            st, ok2 = o.wait_state(lambda s: s == "Paused", 120 + 10 * pause_layer)
            sc["paused"] = ok2
            sc["state_after_pause"] = st
            if ok2:
                sc["layer_when_paused"] = counter(a.wait)
            o.post("/api/job", {"command": "pause", "action": "resume"})
            st, ok2 = o.wait_state(lambda s: s == "Printing", a.wait)
            sc["resumed"] = ok2
            time.sleep(1.0)
            o.post("/api/job", {"command": "cancel"})
            st, ok2 = o.wait_state(lambda s: s.startswith("Operational"), a.wait)
            sc["operational_after_cancel"] = ok2
            out["scenarios"]["reprint"] = sc
        out["final_state"] = o.state()
        o.post("/api/connection", {"command": "disconnect"})
    except Done:
        pass
    except Exception as e:
        out["error"] = repr(e)
    finally:
        out["seconds"] = round(time.monotonic() - t0, 1)
        proc.terminate()
        try:
            proc.wait(15)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()
        if "error" in out:
            with open(os.path.join(base, "serve.log"), errors="replace") as f:
                out["serve_log_tail"] = f.read().splitlines()[-30:]
        try:
            with open(os.path.join(base, "logs", "octoprint.log"), errors="replace") as f:
                lines = f.read().splitlines()
            out["log_tail"] = [
                l[24:] for l in lines if "comm" in l or "layerpause" in l or "ERROR" in l
            ][-40:]
        except OSError:
            pass
        shutil.rmtree(base, ignore_errors=True)
    print(json.dumps(out))
    return 0 if "error" not in out else 1


if __name__ == "__main__":
    sys.exit(main())
