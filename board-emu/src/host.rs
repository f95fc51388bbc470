//! The scripted host on USART1 (the TFT header at 115200 Bd) or on the USB CDC port, talking
//! as `sim run`'s host does (`sim::hostlink`, modelled on printcore and OctoPrint): `M110 N0`
//! first, then every job line as `N<n> <text>*<checksum>` (comments stripped, or kept with
//! [`Host::keep_comments`]), the next only after the printer's `ok`, `Resend: <n>` rewinding
//! to that line; realtime requests (`M24`) written at once, unnumbered.

use crate::time::Cyc;
use crate::usart::Usart;
use crate::usbhost::UsbHost;
use std::collections::VecDeque;

/// A port the host talks through: the UART's line or the USB CDC port.
pub trait Wire {
    /// Every byte the printer sent, with the time it arrived.
    fn received(&self) -> &[(Cyc, u8)];
    /// Whether bytes the host wrote still wait to go out.
    fn busy(&self) -> bool;
    /// Writes bytes at `now`.
    fn send(&mut self, now: Cyc, bytes: &[u8]);
}

impl Wire for Usart {
    fn received(&self) -> &[(Cyc, u8)] {
        &self.tx_log
    }
    fn busy(&self) -> bool {
        !self.host_tx.is_empty()
    }
    fn send(&mut self, _now: Cyc, bytes: &[u8]) {
        self.host_tx.extend(bytes);
    }
}

impl Wire for UsbHost {
    fn received(&self) -> &[(Cyc, u8)] {
        &self.rx_log
    }
    fn busy(&self) -> bool {
        !self.host_tx.is_empty()
    }
    fn send(&mut self, now: Cyc, bytes: &[u8]) {
        self.write(now, bytes);
    }
}

/// A line the host queued, numbered or not.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Out {
    /// Numbered, waits for `ok`.
    Line(String),
    /// Realtime: written at once, answered with its own `ok`.
    Now(String),
}

/// The host.
#[derive(Clone, Debug, Default)]
pub struct Host {
    queue: VecDeque<Out>,
    /// Numbered lines sent, by number (for resends).
    sent: Vec<String>,
    /// Lines waiting for their `ok`.
    in_flight: usize,
    next_n: u64,
    rx_cursor: usize,
    partial: Vec<u8>,
    /// Every line the printer sent, with its time.
    pub received: Vec<(Cyc, String)>,
    /// `ok`s received.
    pub oks: u64,
    /// Job lines keep their comments (slicer layer markers reach the printer).
    pub keep_comments: bool,
    /// Resend requests honoured.
    pub resends: u64,
}

/// Marlin's checksum: XOR of every byte of `N<n> <text>`.
fn checksum(s: &str) -> u8 {
    s.bytes().fold(0, |a, b| a ^ b)
}

/// A job line without its comment and surrounding blanks (`None`: nothing to send).
pub fn strip(line: &str) -> Option<&str> {
    let t = line.split(';').next().unwrap_or("").trim();
    (!t.is_empty()).then_some(t)
}

impl Host {
    /// A host that will reset the line numbers first.
    pub fn new() -> Self {
        let mut h = Host::default();
        h.queue.push_back(Out::Now("M110 N0".into()));
        h
    }

    /// Queues job lines (comments stripped unless kept, blank lines dropped). A line that
    /// is only a comment is sent as it is when comments are kept.
    pub fn send_lines<'s>(&mut self, lines: impl IntoIterator<Item = &'s str>) {
        for l in lines {
            let t = if self.keep_comments {
                Some(l.trim()).filter(|t| !t.is_empty())
            } else {
                strip(l)
            };
            if let Some(t) = t {
                self.queue.push_back(Out::Line(t.to_string()));
            }
        }
    }

    /// A realtime request: written as soon as the wire is free, ahead of the job lines still
    /// queued (as OctoPrint's emergency commands and printcore's `send_now` go out).
    pub fn send_now(&mut self, line: &str) {
        let at = self
            .queue
            .iter()
            .position(|o| matches!(o, Out::Line(_)))
            .unwrap_or(self.queue.len());
        self.queue.insert(at, Out::Now(line.to_string()));
    }

    /// Nothing queued and nothing waiting for `ok`.
    pub fn idle(&self) -> bool {
        self.queue.is_empty() && self.in_flight == 0
    }

    /// Lines still queued.
    pub fn queued(&self) -> usize {
        self.queue.len()
    }

    /// Reads what the printer said and writes what may go next.
    pub fn poll(&mut self, wire: &mut dyn Wire, now: Cyc) {
        let got = wire.received();
        let new: Vec<(Cyc, u8)> = got.get(self.rx_cursor..).unwrap_or(&[]).to_vec();
        self.rx_cursor = got.len();
        for (t, b) in new {
            if b == b'\n' {
                let line = String::from_utf8_lossy(&self.partial)
                    .trim_end()
                    .to_string();
                self.partial.clear();
                self.on_line(t, line);
            } else {
                self.partial.push(b);
            }
        }
        // Nothing is written while earlier bytes still wait on the wire.
        if wire.busy() {
            return;
        }
        if let Some(o) = self.queue.front().cloned() {
            match o {
                Out::Now(l) => {
                    self.queue.pop_front();
                    wire.send(now, format!("{l}\n").as_bytes());
                    self.in_flight += 1;
                }
                Out::Line(l) if self.in_flight == 0 => {
                    self.queue.pop_front();
                    self.next_n += 1;
                    let body = format!("N{} {}", self.next_n, l);
                    let cs = checksum(&body);
                    wire.send(now, format!("{body}*{cs}\n").as_bytes());
                    self.sent.push(l);
                    self.in_flight = 1;
                }
                Out::Line(_) => {}
            }
        }
    }

    fn on_line(&mut self, t: Cyc, line: String) {
        if line.starts_with("ok") {
            self.oks += 1;
            self.in_flight = self.in_flight.saturating_sub(1);
        } else if let Some(n) = line
            .strip_prefix("Resend:")
            .or_else(|| line.strip_prefix("rs"))
            .and_then(|s| s.trim().parse::<u64>().ok())
        {
            // Re-queue every numbered line from `n` on (the `ok` that follows is counted).
            self.resends += 1;
            let from = n.saturating_sub(1) as usize;
            let again: Vec<Out> = self
                .sent
                .drain(from.min(self.sent.len())..)
                .map(Out::Line)
                .collect();
            self.next_n = from as u64;
            for o in again.into_iter().rev() {
                self.queue.push_front(o);
            }
        }
        self.received.push((t, line));
    }

    /// The first received line containing `pat`, with its time.
    pub fn find(&self, pat: &str) -> Option<&(Cyc, String)> {
        self.received.iter().find(|(_, l)| l.contains(pat))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbered_with_checksum_one_per_ok() {
        let mut h = Host::new();
        let mut u = Usart::default();
        h.send_lines(["G28 ; home", "", "G1 X1"]);
        h.poll(&mut u, 0);
        let out: Vec<u8> = u.host_tx.drain(..).collect();
        assert_eq!(String::from_utf8(out).unwrap(), "M110 N0\n");
        u.tx_log.extend(b"ok\n".iter().map(|&b| (0, b)));
        h.poll(&mut u, 0);
        let out: Vec<u8> = u.host_tx.drain(..).collect();
        let want = format!("N1 G28*{}\n", checksum("N1 G28"));
        assert_eq!(String::from_utf8(out).unwrap(), want);
        h.poll(&mut u, 0);
        assert!(u.host_tx.is_empty(), "one line in flight");
    }
}
