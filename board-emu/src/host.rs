//! The host on USART1 (the TFT header at 115200 Bd), talking as `sim run`'s host does
//! (`sim::hostlink`, modelled on printcore and OctoPrint): `M110 N0` first, then every job line
//! without its comment as `N<n> <text>*<checksum>`, the next only after the printer's `ok`,
//! `Resend: <n>` rewinding to that line; realtime requests (`M24`) written at once, unnumbered.

use crate::time::Cyc;
use crate::usart::Usart;
use std::collections::VecDeque;

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

    /// Queues job lines (comments stripped, blank lines dropped).
    pub fn send_lines<'s>(&mut self, lines: impl IntoIterator<Item = &'s str>) {
        for l in lines {
            if let Some(t) = strip(l) {
                self.queue.push_back(Out::Line(t.to_string()));
            }
        }
    }

    /// Queues a realtime request.
    pub fn send_now(&mut self, line: &str) {
        self.queue.push_back(Out::Now(line.to_string()));
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
    pub fn poll(&mut self, uart: &mut Usart) {
        let new: Vec<(Cyc, u8)> = uart.tx_log[self.rx_cursor..].to_vec();
        self.rx_cursor = uart.tx_log.len();
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
        if !uart.host_tx.is_empty() {
            return;
        }
        while let Some(o) = self.queue.front().cloned() {
            match o {
                Out::Now(l) => {
                    self.queue.pop_front();
                    uart.host_tx.extend(l.bytes().chain([b'\n']));
                    self.in_flight += 1;
                }
                Out::Line(l) if self.in_flight == 0 => {
                    self.queue.pop_front();
                    self.next_n += 1;
                    let body = format!("N{} {}", self.next_n, l);
                    let cs = checksum(&body);
                    uart.host_tx.extend(format!("{body}*{cs}\n").bytes());
                    self.sent.push(l);
                    self.in_flight = 1;
                }
                Out::Line(_) => break,
            }
            if !uart.host_tx.is_empty() {
                break;
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
        h.poll(&mut u);
        let out: Vec<u8> = u.host_tx.drain(..).collect();
        assert_eq!(String::from_utf8(out).unwrap(), "M110 N0\n");
        u.tx_log.extend(b"ok\n".iter().map(|&b| (0, b)));
        h.poll(&mut u);
        let out: Vec<u8> = u.host_tx.drain(..).collect();
        let want = format!("N1 G28*{}\n", checksum("N1 G28"));
        assert_eq!(String::from_utf8(out).unwrap(), want);
        h.poll(&mut u);
        assert!(u.host_tx.is_empty(), "one line in flight");
    }
}
