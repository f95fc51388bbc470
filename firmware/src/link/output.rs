//! The link's output: responses formatted into the byte ring (ASCII only, never cut) and
//! drained by the driver.

use super::{HostLink, Response, OUT_CAP};
use core::fmt::{self, Write};
use heapless::Deque;

impl HostLink {
    /// Queue one response (a line end is added). Returns false, and counts it in
    /// [`LinkStats::output_dropped`](super::LinkStats::output_dropped), if it does not fit the output ring: it is then dropped
    /// whole, never cut.
    pub fn respond(&mut self, r: Response<'_>) -> bool {
        let before = self.out.len();
        let written = match r {
            // The most frequent answer, without the formatting machinery.
            Response::Ok if self.output_free() >= 3 => {
                for b in *b"ok\n" {
                    let _ = self.out.push_back(b);
                }
                Ok(())
            }
            r => writeln!(Ring(&mut self.out), "{r}"),
        };
        if written.is_err() {
            // Did not fit: take back what was written, so a response is never cut.
            self.out.truncate(before);
            self.stats.output_dropped = self.stats.output_dropped.saturating_add(1);
            return false;
        }
        true
    }

    /// Bytes free in the output ring.
    pub fn output_free(&self) -> usize {
        OUT_CAP - self.out.len()
    }

    /// Bytes waiting in the output ring.
    pub fn output_len(&self) -> usize {
        self.out.len()
    }

    /// Move all pending output into `w` (each response is followed by `\n`).
    pub fn write_output<W: Write>(&mut self, w: &mut W) -> fmt::Result {
        let mut chunk = [0u8; 64];
        while !self.out.is_empty() {
            let n = self.read_output(&mut chunk);
            // The ring holds ASCII only.
            let s = core::str::from_utf8(chunk.get(..n).unwrap_or(&[])).map_err(|_| fmt::Error)?;
            w.write_str(s)?;
        }
        Ok(())
    }

    /// Move up to `buf.len()` bytes of pending output into `buf` (for a UART/DMA driver);
    /// returns the count.
    pub fn read_output(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for slot in buf.iter_mut() {
            match self.out.pop_front() {
                Some(b) => {
                    *slot = b;
                    n += 1;
                }
                None => break,
            }
        }
        n
    }
}

/// Writes into the output ring, ASCII only (others become `?`).
struct Ring<'a>(&'a mut Deque<u8, OUT_CAP>);

impl Write for Ring<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        if s.is_ascii() {
            for &b in s.as_bytes() {
                self.0.push_back(b).map_err(|_| fmt::Error)?;
            }
            return Ok(());
        }
        for ch in s.chars() {
            let b = if ch.is_ascii() { ch as u8 } else { b'?' };
            self.0.push_back(b).map_err(|_| fmt::Error)?;
        }
        Ok(())
    }
}
