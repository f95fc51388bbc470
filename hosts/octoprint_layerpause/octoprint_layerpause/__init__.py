"""OctoPrint-LayerPause.

The LayerPause firmware pauses at the next layer boundary and parks by itself (M601, or M25
from a job), says `//action:paused` when parked and `//action:resumed` when printing again,
and takes M601/M602/M25/M24/M524 at once through its emergency parser (`Cap:EMERGENCY_PARSER:1`).
OctoPrint's own Pause stops streaming instead: the firmware then drains its queue and stops
mid-layer without parking. This plugin

* turns OctoPrint's Pause button into `M601` and lets the job stream on until the firmware's
  `//action:paused` (OctoPrint's own action-command handling then shows "Paused");
* turns Resume into `M602` (OctoPrint shows "Printing" on `//action:resumed`) and sends `M524`
  before OctoPrint's own Cancel;
* adds M601, M602, M25, M24 and M524 to OctoPrint's emergency commands (sent at once, not
  behind the stream's next `ok`) for the session, so its terminal can always reach them;
* offers "pause at layer N" (`M761 L<n>`: the pause comes before layer N is printed), and
  reports the pause state and the firmware's layer counter through its API
  (`GET /api/plugin/layerpause`), read from the firmware's `M27` answer (`echo:layer <n>`) and
  its action commands.

Layer numbers are the firmware's: the n-th layer printed, from 1 — the number PrusaSlicer's and
Cura's previews show — whether OctoPrint strips the comments or not, with a purge line in the
start code or not. The firmware restarts the count at every print (OctoPrint sends `M110 N0`
when a print starts); so does this plugin's counter.

Only for the LayerPause firmware: the takeover is active when the firmware's M115 reports
`Cap:PAUSE_AT_LAYER:1` (setting `takeover`: "auto", "always" or "never").
"""

import re

import octoprint.plugin

REALTIME = ["M601", "M602", "M25", "M24", "M524"]
LAYER_RE = re.compile(r"^echo:\s*layer\s+(\d+|-)\s")


class LayerPausePlugin(
    octoprint.plugin.StartupPlugin,
    octoprint.plugin.SettingsPlugin,
    octoprint.plugin.SimpleApiPlugin,
    octoprint.plugin.EventHandlerPlugin,
):
    def __init__(self):
        self.firmware_has_layer_pause = False
        self.state = "idle"  # idle | pause_requested | paused | printing | cancelled
        self.layer = None
        # M27 layer answers seen (a client that asks for a fresh counter waits for this to grow).
        self.layer_reports = 0
        self.scheduled_layer = None

    # ~~ settings

    def get_settings_defaults(self):
        return {"takeover": "auto", "emergency_commands": True}

    def _active(self):
        mode = self._settings.get(["takeover"])
        if mode == "always":
            return True
        if mode == "never":
            return False
        return self.firmware_has_layer_pause

    # ~~ startup: emergency commands, wrap the printer's pause/resume/cancel

    def on_after_startup(self):
        if self._settings.get_boolean(["emergency_commands"]):
            cmds = list(self._settings.global_get(["serial", "emergencyCommands"]) or [])
            for c in REALTIME:
                if c not in cmds:
                    cmds.append(c)
            # In memory only (not saved to config.yaml): read when a connection opens.
            self._settings.global_set(["serial", "emergencyCommands"], cmds)
        printer = self._printer
        orig_pause, orig_resume, orig_cancel = (
            printer.pause_print,
            printer.resume_print,
            printer.cancel_print,
        )

        def pause_print(*args, **kwargs):
            if not self._active() or not printer.is_printing():
                return orig_pause(*args, **kwargs)
            self._logger.info("Pause: M601 (firmware layer pause), the job streams on")
            self.state = "pause_requested"
            printer.commands("M601", tags={"plugin:layerpause"})

        def resume_print(*args, **kwargs):
            if not self._active():
                return orig_resume(*args, **kwargs)
            self._logger.info("Resume: M602")
            printer.commands("M602", tags={"plugin:layerpause"})

        def cancel_print(*args, **kwargs):
            if self._active():
                self._logger.info("Cancel: M524, then OctoPrint's own cancel")
                printer.commands("M524", tags={"plugin:layerpause"})
                self.state = "cancelled"
            return orig_cancel(*args, **kwargs)

        printer.pause_print = pause_print
        printer.resume_print = resume_print
        printer.cancel_print = cancel_print

    # ~~ events: a new print starts a new count (the firmware's restarts at OctoPrint's M110)

    def on_event(self, event, payload):
        if event == "PrintStarted":
            self.layer = None
            self.state = "printing"

    # ~~ hooks

    def on_firmware_capability(self, comm, capability, enabled, already_defined, *a, **kw):
        if capability == "PAUSE_AT_LAYER":
            self.firmware_has_layer_pause = bool(enabled)
            self._logger.info("Firmware layer pause: %s", enabled)

    def on_action(self, comm, line, action, name="", params="", *a, **kw):
        if action == "paused":
            self.state = "paused"
        elif action == "resumed":
            self.state = "printing"
        elif action == "cancel":
            self.state = "cancelled"

    def on_received(self, comm, line, *a, **kw):
        m = LAYER_RE.match(line)
        if m:
            self.layer = None if m.group(1) == "-" else int(m.group(1))
            self.layer_reports += 1
        return line

    # ~~ API: GET state, POST pause_at_layer / clear_schedule / refresh

    def get_api_commands(self):
        return {"pause_at_layer": ["layer"], "clear_schedule": [], "refresh": []}

    def on_api_command(self, command, data):
        import flask

        if command == "pause_at_layer":
            try:
                n = int(data["layer"])
            except (TypeError, ValueError):
                return flask.make_response("layer must be an integer", 400)
            if n < 1:
                return flask.make_response("layers count from 1 (the slicer preview's numbers)", 400)
            self.scheduled_layer = n
            self._printer.commands(f"M761 L{n}", tags={"plugin:layerpause"})
        elif command == "clear_schedule":
            self.scheduled_layer = None
            self._printer.commands("M761 C", tags={"plugin:layerpause"})
        elif command == "refresh":
            self._printer.commands("M27", tags={"plugin:layerpause"})
        return flask.jsonify(self._status())

    def is_api_protected(self):
        return True

    def on_api_get(self, request):
        import flask

        return flask.jsonify(self._status())

    def _status(self):
        return {
            "active": self._active(),
            "firmware_has_layer_pause": self.firmware_has_layer_pause,
            "state": self.state,
            "layer": self.layer,
            "layer_reports": self.layer_reports,
            "scheduled_layer": self.scheduled_layer,
            "octoprint_state": self._printer.get_state_id(),
        }


__plugin_name__ = "LayerPause"
__plugin_pythoncompat__ = ">=3.8,<4"


def __plugin_load__():
    global __plugin_implementation__, __plugin_hooks__
    __plugin_implementation__ = LayerPausePlugin()
    __plugin_hooks__ = {
        "octoprint.comm.protocol.firmware.capabilities": __plugin_implementation__.on_firmware_capability,
        "octoprint.comm.protocol.action": __plugin_implementation__.on_action,
        "octoprint.comm.protocol.gcode.received": __plugin_implementation__.on_received,
    }
