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
  layer     pause at layer N: the plugin's API (M761 L<n>) → "Paused"; the plugin's layer
            counter; resume with the button.
  cancel    OctoPrint's Cancel button → "Operational".

With --two-hosts (another host on the TFT port, tests/hosts/printcore_tft.py) instead:
  twohosts  print; the other host pauses (state "Paused" seen here), OctoPrint's Resume
            button; OctoPrint's Pause button, the other host resumes (state "Printing" seen
            here); Cancel. OctoPrint's serial log is kept to show what reached this port.
With --reconnect instead:
  reconnect print; Pause button → "Paused"; disconnect and connect again (a new session:
            OctoPrint has no job now); terminal M602 (refused by the firmware: the held job's
            host went away) then M524 (cancels it, the head stays parked).

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

API_KEY = "LAYERPAUSETESTKEY0123456789ABCDEF"


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def write_basedir(base, emergency, serial_log=False):
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


def serial_lines(base):
    """OctoPrint's serial log: (direction, text) per line, Recv/Send."""
    try:
        with open(os.path.join(base, "logs", "serial.log"), errors="replace") as f:
            lines = f.read().splitlines()
    except OSError:
        return []
    out = []
    for l in lines:
        for tag in ("Recv: ", "Send: "):
            i = l.find(tag)
            if i >= 0:
                out.append((tag[:4], l[i + len(tag):]))
    return out


def other_scenarios(o, a, out, printing_on, job_cmd, terminal, base):
    sc = {}
    if a.two_hosts:
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
    else:
        sc["printing_on"] = printing_on(60)
        job_cmd("pause")()
        st, ok = o.wait_state(lambda s: s == "Paused", a.wait)
        sc["paused"] = ok
        time.sleep(1)
        o.post("/api/connection", {"command": "disconnect"})
        st, ok = o.wait_state(lambda s: s.startswith("Offline") or s.startswith("Closed"), a.wait)
        sc["disconnected"] = ok
        sc["state_disconnected"] = st
        mark = len(serial_lines(base))
        o.post("/api/connection", {"command": "connect", "port": a.port, "baudrate": 115200})
        st, ok = o.wait_state(lambda s: s.startswith("Operational"), 30)
        sc["reconnected_state"] = st
        time.sleep(2)
        after = [t for d, t in serial_lines(base)[mark:] if d == "Recv"]
        sc["told"] = [t for t in after if "paused: job held" in t]
        mark = len(serial_lines(base))
        terminal("M602")()
        time.sleep(2)
        sc["m602"] = [t for d, t in serial_lines(base)[mark:] if d == "Recv" and "resume" in t]
        mark = len(serial_lines(base))
        terminal("M524")()
        end = time.monotonic() + a.wait
        seen = []
        while time.monotonic() < end:
            seen = [t for d, t in serial_lines(base)[mark:] if d == "Recv"]
            if "//action:cancel" in seen:
                break
            time.sleep(0.2)
        sc["cancel_action"] = "//action:cancel" in seen
        # The head after the cancel (after its park): M400, M114.
        time.sleep(2)
        mark = len(serial_lines(base))
        terminal("M400")()
        terminal("M114")()
        end = time.monotonic() + a.wait
        while time.monotonic() < end:
            m114 = [t for d, t in serial_lines(base)[mark:] if d == "Recv" and t.startswith("X:")]
            if m114:
                sc["m114_after_cancel"] = m114[0]
                break
            time.sleep(0.2)
        sc["state_end"] = o.state()
        out["scenarios"]["reconnect"] = sc
    o.post("/api/connection", {"command": "disconnect"})


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--octoprint", required=True, help="the octoprint executable")
    ap.add_argument("--layers", type=int, default=5)
    ap.add_argument("--pause-layer", type=int, default=3)
    ap.add_argument("--wait", type=float, default=20.0)
    ap.add_argument("--no-emergency", action="store_true")
    ap.add_argument("--two-hosts", action="store_true")
    ap.add_argument("--reconnect", action="store_true")
    a = ap.parse_args()

    t0 = time.monotonic()
    out = {"scenarios": {}}
    base = tempfile.mkdtemp(prefix="octoprint-test-")
    write_basedir(base, not a.no_emergency, serial_log=a.two_hosts or a.reconnect)
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
        while True:
            try:
                out["plugin"] = o.get("/api/plugin/layerpause")
            except Exception as e:
                out["plugin"] = {"error": repr(e)}
            if out["plugin"].get("active") or time.monotonic() > end:
                break
            time.sleep(0.2)

        # The job: the file's first --layers layers plus its end code.
        text = "\n".join(job_lines(a.file, a.layers)) + "\n"
        r = o.s.post(
            o.url + "/api/files/local",
            files={"file": ("job.gcode", text.encode())},
            data={"select": "true", "print": "true"},
            timeout=30,
        )
        r.raise_for_status()

        # heatup: temperatures shown while the firmware waits in M109/M190.
        temps = []
        end = time.monotonic() + 60
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

        def job_cmd(action):
            return lambda: o.post("/api/job", {"command": "pause", "action": action})

        def terminal(cmd):
            return lambda: o.post("/api/printer/command", {"commands": [cmd]})

        if a.two_hosts or a.reconnect:
            other_scenarios(o, a, out, printing_on, job_cmd, terminal, base)
            raise Done()
        pause_resume("button", job_cmd("pause"), job_cmd("resume"))
        if o.state() == "Printing":
            pause_resume("terminal", terminal("M601"), terminal("M602"))
        if o.state() == "Printing":
            pause_resume("m25", terminal("M25"), terminal("M24"))
        if o.state() == "Printing":
            def at_layer():
                o.post(
                    "/api/plugin/layerpause",
                    {"command": "pause_at_layer", "layer": a.pause_layer},
                )

            sc = pause_resume("layer", at_layer, job_cmd("resume"))
            # M27 through the plugin: wait (bounded) for its answer to update the layer.
            before = o.get("/api/plugin/layerpause").get("layer")
            o.post("/api/plugin/layerpause", {"command": "refresh"})
            end = time.monotonic() + a.wait
            while True:
                sc["plugin_after"] = o.get("/api/plugin/layerpause")
                layer = sc["plugin_after"].get("layer")
                if (layer is not None and layer != before) or time.monotonic() > end:
                    break
                time.sleep(0.1)

        # cancel
        sc = {}
        o.post("/api/job", {"command": "cancel"})
        st, ok = o.wait_state(lambda s: s.startswith("Operational"), a.wait)
        sc["operational_after_cancel"] = ok
        sc["state"] = st
        out["scenarios"]["cancel"] = sc
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
