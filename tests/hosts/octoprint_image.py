#!/usr/bin/env python3
"""A real OctoPrint with the LayerPause plugin (hosts/octoprint_layerpause) printing a short job
on the emulated SKR 2's USB port (`board-emu --serve`), through its REST API as a browser
would (the set-up, the API calls and the serial log come from octoprint_drive.py):

  button     print; once printing, its Pause button (with the plugin: the firmware's layer
             pause) → "Paused" after `//action:paused`; its Resume button → "Printing".
  cancel     its Cancel button → "Operational".
  reconnect  print again; Pause → "Paused"; disconnect (the USB port closed: DTR drops, the
             job's host went away) and connect again (DTR raised: a new session): the image
             tells it the job is held; M602 is refused; M524 cancels (`//action:cancel`).

Prints one JSON object with what each scenario saw.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import yaml

from octoprint_drive import Octo, free_port, recv_since, serial_lines, wait_recv, write_basedir


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", required=True)
    ap.add_argument("--file", required=True)
    ap.add_argument("--octoprint", required=True)
    ap.add_argument("--wait", type=float, default=90.0)
    a = ap.parse_args()

    t0 = time.monotonic()
    out = {"scenarios": {}}
    base = tempfile.mkdtemp(prefix="octoprint-image-")
    write_basedir(base, True, serial_log=True)
    # The emulated board runs below real time on a loaded machine (its report's
    # serve.virtual_per_wall: 0.1-0.5 here): the printer's keep-alives (M113, M155) come that
    # much slower in wall time, and OctoPrint's dead-printer detection would close the
    # connection. It is off, its timeouts raised; nothing else of OctoPrint's changes.
    cfg_path = os.path.join(base, "config.yaml")
    with open(cfg_path) as f:
        cfg = yaml.safe_load(f)
    cfg["serial"]["timeout"] = {"communication": 120, "communicationBusy": 60}
    cfg["serial"]["maxCommunicationTimeouts"] = {"idle": 0, "printing": 0, "long": 0}
    with open(cfg_path, "w") as f:
        yaml.safe_dump(cfg, f)
    port = free_port()
    log = open(os.path.join(base, "serve.log"), "w")
    proc = subprocess.Popen(
        [a.octoprint, "serve", "--iknowwhatimdoing", "--basedir", base, "--host", "127.0.0.1",
         "--port", str(port)],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    o = Octo(f"http://127.0.0.1:{port}")
    text = open(a.file).read()
    try:
        end = time.monotonic() + 120
        while True:
            try:
                out["version"] = o.get("/api/version")
                break
            except Exception:
                if time.monotonic() > end or proc.poll() is not None:
                    raise RuntimeError("OctoPrint did not come up")
                time.sleep(0.3)
        out["startup_s"] = round(time.monotonic() - t0, 1)

        def connect():
            o.post("/api/connection", {"command": "connect", "port": a.port, "baudrate": 115200})
            return o.wait_state(lambda s: s.startswith("Operational"), a.wait)

        st, ok = connect()
        out["connected"] = ok
        if not ok:
            raise RuntimeError(f"not operational: {st}")
        end = time.monotonic() + 30
        while True:
            out["plugin"] = o.get("/api/plugin/layerpause")
            if out["plugin"].get("active") or time.monotonic() > end:
                break
            time.sleep(0.2)

        def start_print():
            r = o.s.post(
                o.url + "/api/files/local",
                files={"file": ("job.gcode", text.encode())},
                data={"select": "true", "print": "true"},
                timeout=30,
            )
            r.raise_for_status()

        def job_cmd(action):
            o.post("/api/job", {"command": "pause", "action": action})

        def terminal(cmd):
            o.post("/api/printer/command", {"commands": [cmd]})

        def printing_past(pos_bytes):
            end = time.monotonic() + a.wait
            while time.monotonic() < end:
                job = o.get("/api/job")
                pos = (job.get("progress") or {}).get("filepos") or 0
                if job.get("state") == "Printing" and pos >= pos_bytes:
                    return True
                time.sleep(0.05)
            return False

        # Pause once the second layer's lines are being sent (the printer then prints the first).
        first_layer = text.find(";LAYER:1")
        start_print()
        sc = {"printing": printing_past(first_layer)}
        mark = len(serial_lines(base))
        job_cmd("pause")
        st, ok = o.wait_state(lambda s: s == "Paused", a.wait)
        sc["paused"] = ok
        sc["parked"] = wait_recv(base, mark, lambda t: t == "//action:paused", a.wait) is not None
        job_cmd("resume")
        st, ok = o.wait_state(lambda s: s == "Printing", a.wait)
        sc["resumed"] = ok
        sc["resumed_action"] = (
            wait_recv(base, mark, lambda t: t == "//action:resumed", a.wait) is not None
        )
        out["scenarios"]["button"] = sc

        sc = {}
        o.post("/api/job", {"command": "cancel"})
        st, ok = o.wait_state(lambda s: s.startswith("Operational"), a.wait)
        sc["operational_after_cancel"] = ok
        sc["state"] = st
        out["scenarios"]["cancel"] = sc

        sc = {}
        start_print()
        sc["printing"] = printing_past(first_layer)
        job_cmd("pause")
        st, ok = o.wait_state(lambda s: s == "Paused", a.wait)
        sc["paused"] = ok
        o.post("/api/connection", {"command": "disconnect"})
        st, ok = o.wait_state(lambda s: s.startswith("Offline") or s.startswith("Closed"), a.wait)
        sc["disconnected"] = ok
        time.sleep(1.0)
        mark = len(serial_lines(base))
        st, ok = connect()
        sc["reconnected"] = ok
        told = wait_recv(base, mark, lambda t: "paused: job held" in t, a.wait)
        sc["told"] = told
        if not told:
            sc["recv_after_connect"] = recv_since(base, mark)[:12]
        mark = len(serial_lines(base))
        terminal("M602")
        sc["m602"] = wait_recv(base, mark, lambda t: "resume" in t, a.wait)
        mark = len(serial_lines(base))
        terminal("M524")
        sc["cancel_action"] = (
            wait_recv(base, mark, lambda t: t == "//action:cancel", a.wait) is not None
        )
        out["scenarios"]["reconnect"] = sc
        out["final_state"] = o.state()
        o.post("/api/connection", {"command": "disconnect"})
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
        try:
            with open(os.path.join(base, "logs", "octoprint.log"), errors="replace") as f:
                lines = f.read().splitlines()
            out["log_tail"] = [
                l[24:] for l in lines if "comm" in l or "layerpause" in l or "ERROR" in l
            ][-30:]
        except OSError:
            pass
        shutil.rmtree(base, ignore_errors=True)
    print(json.dumps(out))
    return 0 if "error" not in out else 1


if __name__ == "__main__":
    sys.exit(main())
