//! Line assembly: bytes of one line in, a bounded copy of the line plus what is needed to check
//! it (line number, checksum) out — however long the line is.
//!
//! The command text is kept up to [`LINE_CAP`] bytes; past that the line is marked cut (its
//! head is kept). Comment text (after `;`) is kept up to [`COMMENT_KEEP`] bytes and the rest
//! dropped as it arrives: enough for every layer marker, never an error. The checksum is
//! computed as the bytes arrive (XOR of everything before the last `*`, as Marlin's
//! `strrchr(command, '*')`), so a line whose comment was dropped is still checked exactly, and a
//! `*` inside a comment the host kept (`G1 X10 ; a*0.85*44`) is text, not the checksum.

use super::{COMMENT_KEEP, LINE_CAP};
use heapless::Vec;

/// What followed the last `*` of the line so far.
#[derive(Clone, Copy, Debug, Default)]
struct Tail {
    /// Value of the digits after the `*`.
    value: u32,
    /// Number of digits after the `*`.
    digits: u8,
    /// Blanks after the digits (allowed at the end of the line).
    blank_after: bool,
    /// Anything else after the `*` (then it is not a checksum).
    other: bool,
}

/// One line being assembled. See the module documentation.
#[derive(Clone, Debug, Default)]
pub(super) struct Assembler {
    buf: Vec<u8, LINE_CAP>,
    /// A byte other than a blank has arrived.
    started: bool,
    /// Command text beyond [`LINE_CAP`] was dropped.
    code_cut: bool,
    /// Bytes of comment kept so far, once a `;` has arrived.
    comment: Option<usize>,
    /// XOR of every byte of the line so far (from the first non-blank).
    xor: u8,
    /// The last `*`: XOR of the bytes before it, and its index in `buf` if it was kept.
    star: Option<(u8, Option<usize>)>,
    tail: Tail,
    /// Where the line stands in the pattern of a line end lost between two numbered lines.
    merge: MergeScan,
    /// That pattern was seen: a checksum, then the start of another numbered line.
    merged: bool,
}

/// The signature of two lines merged by a lost (or corrupted) line end: a checksum (`*` and
/// one to three digits, a fourth if the line end became a digit), at most two other bytes
/// (the line end turned into noise, a CR of CR LF), then `N` and a digit or `-` — the next
/// numbered line (`N19 M400*317N19 M400*31`). A `*` in comment text (`; a*0.85`) is not
/// followed by that, so it is not taken for a merge.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum MergeScan {
    /// Outside the pattern.
    #[default]
    Idle,
    /// After a `*` and this many digits.
    Digits(u8),
    /// After the digits and this many other bytes.
    Gap(u8),
    /// After the `N`.
    N,
}

impl MergeScan {
    /// The state after byte `b`; true when the pattern is complete.
    fn step(self, b: u8) -> (Self, bool) {
        let n = matches!(b, b'N' | b'n');
        match self {
            _ if b == b'*' => (Self::Digits(0), false),
            Self::Digits(k) if b.is_ascii_digit() && k < 4 => (Self::Digits(k + 1), false),
            Self::Digits(0) => (Self::Idle, false),
            Self::Digits(_) | Self::Gap(_) if n => (Self::N, false),
            Self::Digits(_) => (Self::Gap(1), false),
            Self::Gap(g) if g < 2 => (Self::Gap(g + 1), false),
            Self::N => (Self::Idle, b.is_ascii_digit() || b == b'-'),
            Self::Gap(_) | Self::Idle => (Self::Idle, false),
        }
    }
}

/// A complete line, ready to be checked.
pub(super) struct Assembled<'a> {
    /// The kept text, without the checksum (line number included, blanks trimmed).
    pub raw: &'a [u8],
    /// The checksum written at the end of the line (`*<0..=255>`), if any.
    pub checksum: Option<u8>,
    /// Whether that checksum matches the line.
    pub sum_ok: bool,
    /// A checksum, and before it the signature of a lost line end ([`MergeScan`]): never a
    /// valid line.
    pub merged: bool,
    /// Command text was longer than [`LINE_CAP`]: `raw` is its head.
    pub cut: bool,
}

impl Assembler {
    pub const fn new() -> Self {
        Assembler {
            buf: Vec::new(),
            started: false,
            code_cut: false,
            comment: None,
            xor: 0,
            star: None,
            tail: Tail {
                value: 0,
                digits: 0,
                blank_after: false,
                other: false,
            },
            merge: MergeScan::Idle,
            merged: false,
        }
    }

    /// Start a new line.
    pub fn clear(&mut self) {
        *self = Self::new();
    }

    /// Add one byte of the line (not a line end).
    pub fn push(&mut self, b: u8) {
        let blank = matches!(b, b' ' | b'\t');
        if !self.started {
            if blank {
                return;
            }
            self.started = true;
        }
        if b == b'*' {
            // Index it will have in `buf`, if it is kept.
            let at = self.buf.len();
            let kept = self.keep(b);
            self.star = Some((self.xor, kept.then_some(at)));
            self.tail = Tail::default();
        } else {
            if self.star.is_some() {
                let t = &mut self.tail;
                match b {
                    b'0'..=b'9' if !t.blank_after && t.digits < 4 => {
                        t.value = t.value * 10 + u32::from(b - b'0');
                        t.digits += 1;
                    }
                    b' ' | b'\t' => t.blank_after = true,
                    _ => t.other = true,
                }
            }
            self.keep(b);
        }
        let (merge, merged) = self.merge.step(b);
        self.merge = merge;
        self.merged |= merged;
        self.xor ^= b;
    }

    /// Keep `b` in the buffer if the rules allow; returns whether it was kept.
    fn keep(&mut self, b: u8) -> bool {
        match self.comment {
            None => {
                if b == b';' {
                    self.comment = Some(0);
                }
                let kept = self.buf.push(b).is_ok();
                if !kept && self.comment.is_none() {
                    self.code_cut = true;
                }
                kept
            }
            Some(n) if n < COMMENT_KEEP => {
                let kept = self.buf.push(b).is_ok();
                if kept {
                    self.comment = Some(n + 1);
                }
                kept
            }
            Some(_) => false,
        }
    }

    /// Nothing but blanks so far.
    pub fn is_empty(&self) -> bool {
        !self.started
    }

    /// The line as it stands, for checking.
    pub fn line(&self) -> Assembled<'_> {
        let t = self.tail;
        let checksum = match self.star {
            Some(_) if !t.other && (1..=3).contains(&t.digits) => u8::try_from(t.value).ok(),
            _ => None,
        };
        let (raw, sum_ok) = match (checksum, self.star) {
            (Some(cs), Some((xor, at))) => {
                let raw = match at {
                    Some(i) => self.buf.get(..i).unwrap_or(&[]),
                    None => &self.buf[..],
                };
                (raw, xor == cs)
            }
            _ => (&self.buf[..], false),
        };
        Assembled {
            raw: trim(raw),
            checksum,
            sum_ok,
            merged: checksum.is_some() && self.merged,
            cut: self.code_cut,
        }
    }
}

/// Trim spaces and tabs at both ends.
pub(super) fn trim(s: &[u8]) -> &[u8] {
    let start = s.iter().position(|c| !matches!(c, b' ' | b'\t'));
    let end = s.iter().rposition(|c| !matches!(c, b' ' | b'\t'));
    match (start, end) {
        (Some(a), Some(b)) => s.get(a..=b).unwrap_or(&[]),
        _ => &[],
    }
}
