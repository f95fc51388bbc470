//! The session's serial ports: one pseudo-terminal per firmware port (USB always, the TFT
//! UART with `--tft`), read with flow control, written as the firmware answers, and watched for
//! a host that opens or closes it.
//!
//! The sim does not keep the terminal's own end open, so the kernel tells whether a host has
//! it: the master side reports a hang-up (`POLLHUP`, reads fail with `EIO`) while nobody holds
//! the device. A host opening the device is a session starting on that port, its last close a
//! session ending ([`firmware::printer::Printer::port_session`]), as DTR is on the board's USB
//! port. Output for a port nobody holds is dropped once a host has gone away (a new host
//! starts afresh); before the first host it waits for it (the power-up messages).

use super::pty::open_pty;
use super::track::{note_request, PauseTrack, Sniffer};
use crate::exec::PrinterExec;
use crate::port::Executive as _;
use crate::recorder::Recorder;
use anyhow::Context;
use firmware::link::PortId;
use std::os::fd::{AsFd, OwnedFd};
use std::path::PathBuf;

/// One pseudo-terminal in front of one firmware port.
pub(super) struct PtyPort {
    pub(super) id: PortId,
    master: OwnedFd,
    pub(super) path: PathBuf,
    /// Bytes read and not yet taken by the firmware (flow control: the device is not read
    /// while [`firmware::link::SCAN_WINDOW`] bytes wait, so the firmware's emergency scan
    /// sees that far ahead and the rest stays in the pty).
    rx_pending: Vec<u8>,
    /// When the bytes of `rx_pending` were read from the device: (bytes, virtual µs), oldest
    /// first.
    rx_reads: std::collections::VecDeque<(usize, u64)>,
    /// Output the host has not read yet.
    tx_pending: Vec<u8>,
    /// A host holds the device.
    open: bool,
    /// A host has held it: until then output waits for the first host (the power-up
    /// messages); after a host went away, output for nobody is dropped.
    ever_open: bool,
    /// Lines seen on this port (for the record).
    pub(super) sniff: Sniffer,
    /// Since when (real time) the host owes its reply to an `ok` written to it: no byte
    /// from it since (see [`super::clock`]).
    owed_since: Option<std::time::Instant>,
    /// Since when (real time) a host holds the device while the firmware has not been told
    /// yet (see [`OPEN_SETTLE`]).
    opening_since: Option<std::time::Instant>,
}

/// How long a host holds the device before the firmware hears of the new session. A host's
/// serial library empties its input right after it opens the device (pyserial's `open()`
/// calls `reset_input_buffer()`): what the firmware says first to a new session (a held job,
/// `//action:paused`) must come after that, or it is flushed away unread (OctoPrint's
/// reconnect missed it about one time in two). Nothing is read from the device meanwhile.
const OPEN_SETTLE: std::time::Duration = std::time::Duration::from_millis(100);

impl PtyPort {
    /// `control_bytes`: single control bytes are requests on this port (as the firmware is
    /// told), for the record's notes.
    pub(super) fn open(id: PortId, control_bytes: bool) -> anyhow::Result<Self> {
        let (master, slave, path) = open_pty()?;
        // Not kept: the master then sees whether a host holds the device.
        drop(slave);
        Ok(Self {
            id,
            master,
            path,
            rx_pending: Vec::new(),
            rx_reads: std::collections::VecDeque::new(),
            tx_pending: Vec::new(),
            open: false,
            ever_open: false,
            sniff: Sniffer::with_control_bytes(control_bytes),
            owed_since: None,
            opening_since: None,
        })
    }

    /// Whether the host owes its reply to an `ok` and has not had `grace` of real time yet
    /// (a host with nothing more to send never replies: after `grace` it owes nothing).
    pub(super) fn owes_reply(&self, grace: std::time::Duration) -> bool {
        self.open && self.owed_since.is_some_and(|t| t.elapsed() < grace)
    }

    /// Whether nothing is pending in either direction.
    pub(super) fn drained(&self) -> bool {
        self.tx_pending.is_empty()
    }

    fn hung_up(&self) -> bool {
        super::pty::hung_up(self.master.as_fd())
    }

    /// A host opened or closed the device since the last call: tell the firmware.
    pub(super) fn watch_session(&mut self, fw: &mut PrinterExec, now_us: u64) {
        let open = !self.hung_up();
        if !open || self.open {
            self.opening_since = None;
        } else if self
            .opening_since
            .get_or_insert_with(std::time::Instant::now)
            .elapsed()
            < OPEN_SETTLE
        {
            return;
        }
        if open != self.open {
            self.open = open;
            self.ever_open |= open;
            if !open {
                self.rx_pending.clear();
                self.rx_reads.clear();
                self.tx_pending.clear();
            }
            self.sniff.new_session();
            fw.port_session(self.id, open, now_us);
        }
    }

    /// Offer pending bytes to the firmware, and read the device while fewer than
    /// [`firmware::link::SCAN_WINDOW`] bytes wait (the firmware takes what it has room for
    /// and scans the rest for M112/M108/M410); realtime requests seen are noted for the record.
    pub(super) fn receive(
        &mut self,
        fw: &mut PrinterExec,
        now_us: u64,
        pauses: &mut Vec<PauseTrack>,
        rec: &Recorder,
    ) -> anyhow::Result<bool> {
        let mut got = false;
        let mut buf = [0u8; 4096];
        if self.opening_since.is_some() {
            return Ok(got);
        }
        loop {
            if !self.rx_pending.is_empty() {
                let n = fw.receive_on(self.id, &self.rx_pending, now_us);
                let mut reqs = Vec::new();
                let parked = fw.status().state == crate::port::State::Paused;
                // Each taken byte with the time it was read from the device.
                let mut at = 0;
                while at < n {
                    let Some((len, read_us)) = self.rx_reads.front_mut() else {
                        break;
                    };
                    let k = (*len).min(n - at);
                    self.sniff
                        .feed(&self.rx_pending[at..at + k], &mut reqs, *read_us, parked);
                    *len -= k;
                    at += k;
                    if *len == 0 {
                        self.rx_reads.pop_front();
                    }
                }
                self.rx_pending.drain(..n);
                for r in reqs {
                    note_request(pauses, r, now_us, rec, fw);
                }
                if self.rx_pending.len() >= firmware::link::SCAN_WINDOW {
                    return Ok(got);
                }
            }
            match nix::unistd::read(self.master.as_fd(), &mut buf) {
                Ok(0) => return Ok(got),
                Ok(n) => {
                    got = true;
                    self.owed_since = None;
                    self.rx_pending.extend_from_slice(&buf[..n]);
                    self.rx_reads.push_back((n, now_us));
                }
                // EIO: nobody holds the device (see the module documentation).
                Err(nix::errno::Errno::EAGAIN | nix::errno::Errno::EIO) => return Ok(got),
                Err(e) => return Err(e).context("reading the pseudo-terminal"),
            }
        }
    }

    /// Take the firmware's output for this port and write what the device takes. Returns
    /// whether it held answers (not only unsolicited temperature reports and `busy:`
    /// keep-alives, which do not keep an idle session alive).
    pub(super) fn send(&mut self, fw: &mut PrinterExec, now_us: u64) -> anyhow::Result<bool> {
        let mut out = String::new();
        fw.take_output_on(self.id, &mut out);
        // When the firmware answered (not when the host read it).
        self.sniff.answered(&out, now_us);
        let answers = out.lines().any(|l| {
            let l = l.trim_start();
            !l.starts_with("T:") && !l.starts_with("busy:")
        });
        if !self.open && self.ever_open {
            return Ok(false);
        }
        self.tx_pending.extend_from_slice(out.as_bytes());
        if !self.open {
            return Ok(false);
        }
        if !self.tx_pending.is_empty() {
            match nix::unistd::write(&self.master, &self.tx_pending) {
                Ok(w) => {
                    let wrote_ok = self.tx_pending[..w]
                        .split(|&b| b == b'\n')
                        .any(|l| l.starts_with(b"ok"));
                    if wrote_ok && self.owed_since.is_none() {
                        self.owed_since = Some(std::time::Instant::now());
                    }
                    self.tx_pending.drain(..w);
                }
                Err(nix::errno::Errno::EAGAIN | nix::errno::Errno::EIO) => {}
                Err(e) => return Err(e).context("writing the pseudo-terminal"),
            }
        }
        Ok(answers)
    }
}

/// Sleep until a byte arrives on any port or `wait_us` pass.
pub(super) fn wait(ports: &[PtyPort], wait_us: u64) {
    if wait_us == 0 {
        return;
    }
    // A port nobody holds reports a hang-up at once: only the held ones are waited on.
    let held: Vec<_> = ports
        .iter()
        .filter(|p| p.open)
        .map(|p| p.master.as_fd())
        .collect();
    super::pty::wait_readable(&held, std::time::Duration::from_micros(wait_us));
}
