//! Two host ports in front of one executive: the USB serial port and the TFT's UART (the SKR 2
//! has both, and a BigTreeTech touch screen polls `M105` on its UART while a host prints over
//! USB). Each port has its own [`HostLink`]: its own line assembler, line numbers, FIFO and
//! output ring, so a TFT line split around a USB line is still one line. Answers go to the
//! port that asked; notifications (`//action:`, thermal errors, pause messages) go to both.
//!
//! Memory is fixed: [`PORTS`] links of about 4.8 KB each (the 4 KB output ring dominates).

use super::{HostLink, ReceivedLine, Response};
use crate::motion::Realtime;
use core::fmt::{self, Write};

/// Number of host ports.
pub const PORTS: usize = 2;

/// A host port.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PortId {
    /// The USB serial port (the host: OctoPrint, Pronterface, the simulator's pty).
    Usb,
    /// The TFT's UART (a touch screen).
    Tft,
}

impl PortId {
    /// Every port, in index order.
    pub const ALL: [PortId; PORTS] = [PortId::Usb, PortId::Tft];

    /// The port's index, `0..PORTS`.
    pub const fn index(self) -> usize {
        match self {
            PortId::Usb => 0,
            PortId::Tft => 1,
        }
    }

    /// Whether single control bytes (Ctrl-X halt, Ctrl-C cancel, …) are requests on this port
    /// when nothing else is configured: on the USB port, where a host program chose to send
    /// them; never on the TFT's UART, where a display sends none and a stray byte of noise on
    /// its cable would halt or cancel the print (issue 31). [`HostPorts::set_control_bytes`]
    /// changes it.
    pub const fn default_control_bytes(self) -> bool {
        matches!(self, PortId::Usb)
    }

    /// Its name in messages (`USB`, `TFT`).
    pub const fn name(self) -> &'static str {
        match self {
            PortId::Usb => "USB",
            PortId::Tft => "TFT",
        }
    }
}

/// The host links of every port, and where answers go. The executive uses it as it would one
/// link: [`HostPorts::pop_line`] takes lines from the ports in turn and makes the line's port
/// the one [`HostPorts::respond`] answers; [`HostPorts::take_realtime`] does the same for the
/// request it returns until the next call; [`HostPorts::notify`] writes to every port.
#[derive(Clone, Debug, Default)]
pub struct HostPorts {
    links: [HostLink; PORTS],
    /// Port of the last line handed out: its answers (`ok`, reports, errors) go there, also
    /// the `ok` owed for an M400 or an arc, given later.
    line_port: Option<PortId>,
    /// Port of the realtime request being handled (until the next `take_realtime` or
    /// `pop_line`).
    request_port: Option<PortId>,
    /// Lines of that port received before the request and not taken yet (until the next
    /// `take_realtime` or `pop_line`).
    request_lines_ahead: usize,
    /// The port `pop_line` tries first, so one busy port cannot starve the other.
    next: usize,
    /// The line being handled was read from a file (the SD card): see
    /// [`HostPorts::answer_file`].
    file: bool,
}

impl HostPorts {
    /// Idle links on every port.
    pub const fn new() -> Self {
        let mut tft = HostLink::new();
        tft.control_bytes = PortId::Tft.default_control_bytes();
        HostPorts {
            links: [HostLink::new(), tft],
            line_port: None,
            request_port: None,
            request_lines_ahead: 0,
            next: 0,
            file: false,
        }
    }

    /// One port's link (read-only: counters, line numbers).
    pub fn port(&self, p: PortId) -> &HostLink {
        let [usb, tft] = &self.links;
        match p {
            PortId::Usb => usb,
            PortId::Tft => tft,
        }
    }

    fn port_mut(&mut self, p: PortId) -> &mut HostLink {
        let [usb, tft] = &mut self.links;
        match p {
            PortId::Usb => usb,
            PortId::Tft => tft,
        }
    }

    /// Whether single control bytes are requests on port `p` (see
    /// [`PortId::default_control_bytes`], [`HostLink::set_control_bytes`]).
    pub fn set_control_bytes(&mut self, p: PortId, on: bool) {
        self.port_mut(p).set_control_bytes(on);
    }

    /// Bytes received on port `p`; returns how many were taken (see [`HostLink::receive`]).
    pub fn receive(&mut self, p: PortId, bytes: &[u8]) -> usize {
        self.port_mut(p).receive(bytes)
    }

    /// Whether any port holds a realtime request. (The answer port of the last request is
    /// forgotten by the [`HostPorts::take_realtime`] that returns `None`, so a caller that
    /// takes requests until `None` may skip the call when this is false.)
    #[inline]
    pub fn has_realtime(&self) -> bool {
        self.links.iter().any(|l| l.estop || !l.realtime.is_empty())
    }

    /// The next realtime request of any port (emergency stops first). Until the next call (or
    /// [`HostPorts::pop_line`]), [`HostPorts::respond`] answers the port it came from.
    pub fn take_realtime(&mut self) -> Option<Realtime> {
        self.request_port = None;
        self.request_lines_ahead = 0;
        let first = PortId::ALL
            .into_iter()
            .find(|&p| self.port(p).estop)
            .or_else(|| {
                PortId::ALL
                    .into_iter()
                    .find(|&p| !self.port(p).realtime.is_empty())
            })?;
        let (rt, ahead) = self.port_mut(first).take_request()?;
        self.request_port = Some(first);
        self.request_lines_ahead = ahead;
        Some(rt)
    }

    /// How many lines of its port were received before the realtime request being handled
    /// and wait in the FIFO (the moves a pause written in the same burst should stop; issue
    /// 31). 0 outside a request.
    pub fn request_lines_ahead(&self) -> usize {
        self.request_lines_ahead
    }

    /// The oldest checked line of the next port that has one (ports take turns); its answers
    /// go to that port. See [`HostLink::pop_line`].
    pub fn pop_line(&mut self) -> Option<ReceivedLine> {
        for k in 0..PORTS {
            let i = (self.next + k) % PORTS;
            let Some(&p) = PortId::ALL.get(i) else {
                continue;
            };
            if let Some(l) = self.port_mut(p).pop_line() {
                self.next = (i + 1) % PORTS;
                self.line_port = Some(p);
                self.request_port = None;
                self.request_lines_ahead = 0;
                self.file = false;
                return Some(l);
            }
        }
        None
    }

    /// Answers go to the port of the last line handed out again (after a realtime request was
    /// handled): for a line the executive kept waiting for room and takes up now.
    pub fn answer_line_port(&mut self) {
        self.request_port = None;
        self.file = false;
    }

    /// The lines handled from now on (until the next host line) come from a file on the SD
    /// card, as in Marlin: their `ok` goes nowhere, anything else they say goes to every
    /// port. Answers to realtime requests still go to the port that sent them.
    pub fn answer_file(&mut self) {
        self.request_port = None;
        self.file = true;
    }

    /// Answer port `p` (a deferred answer: the card's file list goes to the port that asked).
    pub fn respond_on(&mut self, p: PortId, r: Response<'_>) -> bool {
        self.port_mut(p).respond(r)
    }

    /// Free output bytes of port `p`.
    pub fn output_free_on(&self, p: PortId) -> usize {
        self.port(p).output_free()
    }

    /// Free output bytes of the port the last line came from (its answer goes there).
    pub fn line_output_free(&self) -> usize {
        self.port(self.line_port.unwrap_or(PortId::Usb))
            .output_free()
    }

    /// Lines waiting on every port.
    pub fn lines_waiting(&self) -> usize {
        self.links.iter().map(HostLink::lines_waiting).sum()
    }

    /// The port answers go to now (the USB port before any line).
    pub fn reply_port(&self) -> PortId {
        self.request_port.or(self.line_port).unwrap_or(PortId::Usb)
    }

    /// Answer the port that asked (see the type documentation).
    pub fn respond(&mut self, r: Response<'_>) -> bool {
        if self.file && self.request_port.is_none() {
            match r {
                Response::Ok => {}
                // M105 in a file: the report without the `ok` a host would count.
                Response::Temperatures { report, .. } => self.notify(Response::Temperatures {
                    report,
                    with_ok: false,
                }),
                r => self.notify(r),
            }
            return true;
        }
        let p = self.reply_port();
        self.port_mut(p).respond(r)
    }

    /// Write a notification to every port.
    pub fn notify(&mut self, r: Response<'_>) {
        for l in &mut self.links {
            l.respond(r);
        }
    }

    /// The host on port `p` went away (USB DTR dropped or unplugged, the pty closed): its
    /// line assembly, line numbers, waiting lines and unsent answers are forgotten, as a new
    /// connection starts them anew.
    pub fn reset_port(&mut self, p: PortId) {
        let halted = self.port(p).is_halted();
        let controls = self.port(p).control_bytes();
        *self.port_mut(p) = HostLink::new();
        self.port_mut(p).control_bytes = controls;
        if halted {
            self.port_mut(p).halt();
        }
        if self.line_port == Some(p) {
            self.line_port = None;
        }
        if self.request_port == Some(p) {
            self.request_port = None;
        }
    }

    /// Halt every port (emergency stop): see [`HostLink::halt`].
    pub fn halt(&mut self) {
        for l in &mut self.links {
            l.halt();
        }
    }

    /// Move up to `buf.len()` bytes of port `p`'s output into `buf`; returns the count.
    pub fn read_output(&mut self, p: PortId, buf: &mut [u8]) -> usize {
        self.port_mut(p).read_output(buf)
    }

    /// Move all of port `p`'s output into `w`.
    pub fn write_output<W: Write>(&mut self, p: PortId, w: &mut W) -> fmt::Result {
        self.port_mut(p).write_output(w)
    }
}
