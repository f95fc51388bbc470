//! Reading G-code into motion events for `stats`, `preview` and the time-based resampler.
//!
//! [`GcodeReader`] is the seam: [`FastReader`] is a minimal, allocation-free line reader for
//! the subset that matters for motion (G0–G4, G20/G21, G90/G91, G92, M82/M83, M204, layer
//! comments). When the firmware's parser (`firmware::gcode`/`firmware::layer`) is complete,
//! a reader over it implements the same trait and the tools switch by changing one line
//! ([`default_reader`]).

/// An absolute position: X, Y, Z, E (E as a running total in mm of filament).
pub type Pos4 = [f64; 4];

/// One event read from G-code.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event {
    /// A straight move (arcs arrive as several). `rapid` for G0.
    Move {
        /// Start, absolute.
        from: Pos4,
        /// End, absolute.
        to: Pos4,
        /// Requested feed, mm/s.
        feed_mm_s: f64,
        /// 1-based line number.
        line: u32,
    },
    /// A layer starts (`;LAYER_CHANGE` or `;LAYER:n`); `z_mm` from a `;Z:` comment when it
    /// follows.
    Layer {
        /// 1-based line number.
        line: u32,
    },
    /// `;Z:` comment (height of the layer just started), mm.
    LayerZ(f64),
    /// Dwell (G4), seconds.
    Dwell(f64),
    /// Acceleration change (M204): print (P or S) and travel (T), mm/s²; `None` = unchanged.
    Accel {
        /// Printing acceleration.
        print_mm_s2: Option<f64>,
        /// Travel acceleration.
        travel_mm_s2: Option<f64>,
    },
}

/// A G-code parse error with its line.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("line {line}: {msg}")]
pub struct ReadError {
    /// 1-based line number.
    pub line: u32,
    /// What is wrong.
    pub msg: String,
}

/// What a reader counted.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReadCounts {
    /// Lines read.
    pub lines: u64,
    /// Lines whose command was not understood and skipped (unknown M-codes etc.).
    pub skipped: u64,
}

/// A source of motion events.
pub trait GcodeReader {
    /// Reads all of `input`, calling `sink` for every event in order.
    fn read(&mut self, input: &[u8], sink: &mut dyn FnMut(Event)) -> Result<ReadCounts, ReadError>;
}

/// The reader the tools use.
pub fn default_reader() -> impl GcodeReader {
    FastReader::default()
}

/// Minimal, fast reader for motion (see module docs). Malformed numbers are errors with the
/// line number; unknown commands are skipped and counted.
#[derive(Clone, Debug)]
pub struct FastReader {
    pos: Pos4,
    abs_xyz: bool,
    abs_e: bool,
    inch: bool,
    feed_mm_s: f64,
    /// Longest chord used to expand G2/G3 arcs, mm.
    pub arc_seg_mm: f64,
}

impl Default for FastReader {
    fn default() -> Self {
        FastReader {
            pos: [0.0; 4],
            abs_xyz: true,
            abs_e: true,
            inch: false,
            feed_mm_s: 25.0,
            arc_seg_mm: 0.5,
        }
    }
}

/// Parses a decimal number at the start of `b`: returns the value and bytes used.
#[inline]
fn parse_num(b: &[u8]) -> Option<(f64, usize)> {
    let mut i = 0;
    let mut neg = false;
    match b.first() {
        Some(b'-') => {
            neg = true;
            i = 1;
        }
        Some(b'+') => i = 1,
        _ => {}
    }
    let mut int: u64 = 0;
    let mut digits = 0;
    while let Some(&c) = b.get(i) {
        if c.is_ascii_digit() {
            if digits < 18 {
                int = int * 10 + (c - b'0') as u64;
            }
            digits += 1;
            i += 1;
        } else {
            break;
        }
    }
    if digits > 18 {
        return None; // beyond any machine's range; also keeps `int` exact
    }
    let mut v = int as f64;
    if b.get(i) == Some(&b'.') {
        i += 1;
        let mut frac: u64 = 0;
        let mut fd = 0;
        while let Some(&c) = b.get(i) {
            if c.is_ascii_digit() {
                if fd < 18 {
                    frac = frac * 10 + (c - b'0') as u64;
                    fd += 1;
                }
                digits += 1;
                i += 1;
            } else {
                break;
            }
        }
        const P10: [f64; 19] = [
            1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
            1e16, 1e17, 1e18,
        ];
        v += frac as f64 / P10[fd as usize];
    }
    if digits == 0 {
        return None;
    }
    Some((if neg { -v } else { v }, i))
}

/// Words of one command line (letters A–Z, value): a presence mask and the values.
struct Words {
    mask: u32,
    v: [f64; 26],
}

impl Default for Words {
    #[inline]
    fn default() -> Self {
        Words {
            mask: 0,
            v: [0.0; 26],
        }
    }
}

impl Words {
    #[inline]
    fn get(&self, c: u8) -> Option<f64> {
        let k = (c - b'A') as usize;
        (self.mask & (1 << k) != 0).then(|| self.v[k])
    }
    #[inline]
    fn set(&mut self, c: u8, v: f64) {
        let k = (c - b'A') as usize;
        self.mask |= 1 << k;
        self.v[k] = v;
    }
}

/// Centre of an arc from `from` to `to` given I/J offsets (already scaled) or a radius R
/// (negative R = the long way round).
fn arc_center(
    from: Pos4,
    to: Pos4,
    ij: Option<(f64, f64)>,
    r: Option<f64>,
    ccw: bool,
) -> Result<(f64, f64), &'static str> {
    match (ij, r) {
        (Some((i, j)), _) => Ok((from[0] + i, from[1] + j)),
        (None, Some(r)) => {
            let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
            let d = (dx * dx + dy * dy).sqrt();
            if d < 1e-9 || d > 2.0 * r.abs() + 1e-6 {
                return Err("arc radius too small for its end point");
            }
            let h = (r * r - 0.25 * d * d).max(0.0).sqrt();
            let sgn = if (r > 0.0) == ccw { 1.0 } else { -1.0 };
            Ok((
                from[0] + 0.5 * dx - sgn * h * dy / d,
                from[1] + 0.5 * dy + sgn * h * dx / d,
            ))
        }
        (None, None) => Err("G2/G3 needs I/J or R"),
    }
}

/// Emits an arc as chords no longer than `seg_mm`.
#[allow(clippy::too_many_arguments)]
fn expand_arc(
    from: Pos4,
    to: Pos4,
    c: (f64, f64),
    ccw: bool,
    seg_mm: f64,
    feed_mm_s: f64,
    line: u32,
    sink: &mut dyn FnMut(Event),
) {
    let (cx, cy) = c;
    let r = (from[0] - cx).hypot(from[1] - cy);
    let a0 = (from[1] - cy).atan2(from[0] - cx);
    let a1 = (to[1] - cy).atan2(to[0] - cx);
    let mut sweep = a1 - a0;
    if ccw {
        if sweep <= 1e-9 {
            sweep += std::f64::consts::TAU;
        }
    } else if sweep >= -1e-9 {
        sweep -= std::f64::consts::TAU;
    }
    let n = ((sweep.abs() * r / seg_mm).ceil() as usize).clamp(1, 10_000);
    let mut prev = from;
    for k in 1..=n {
        let t = k as f64 / n as f64;
        let p = if k == n {
            to
        } else {
            let a = a0 + sweep * t;
            [
                cx + r * a.cos(),
                cy + r * a.sin(),
                from[2] + (to[2] - from[2]) * t,
                from[3] + (to[3] - from[3]) * t,
            ]
        };
        sink(Event::Move {
            from: prev,
            to: p,
            feed_mm_s,
            line,
        });
        prev = p;
    }
}

impl FastReader {
    fn arc(
        &mut self,
        w: &Words,
        ccw: bool,
        to: Pos4,
        line: u32,
        sink: &mut dyn FnMut(Event),
    ) -> Result<(), ReadError> {
        let scale = if self.inch { 25.4 } else { 1.0 };
        let ij = match (w.get(b'I'), w.get(b'J')) {
            (None, None) => None,
            (i, j) => Some((i.unwrap_or(0.0) * scale, j.unwrap_or(0.0) * scale)),
        };
        let c = arc_center(self.pos, to, ij, w.get(b'R').map(|r| r * scale), ccw).map_err(|m| {
            ReadError {
                line,
                msg: m.into(),
            }
        })?;
        expand_arc(
            self.pos,
            to,
            c,
            ccw,
            self.arc_seg_mm,
            self.feed_mm_s,
            line,
            sink,
        );
        self.pos = to;
        Ok(())
    }

    fn command(
        &mut self,
        code: u8,
        num: u32,
        w: &Words,
        line: u32,
        sink: &mut dyn FnMut(Event),
    ) -> Result<bool, ReadError> {
        let scale = if self.inch { 25.4 } else { 1.0 };
        match (code, num) {
            (b'G', 0..=3) => {
                if let Some(f) = w.get(b'F') {
                    if f.is_nan() || f <= 0.0 {
                        return Err(ReadError {
                            line,
                            msg: format!("feed F{f} must be > 0"),
                        });
                    }
                    self.feed_mm_s = f * scale / 60.0;
                }
                let mut to = self.pos;
                for (k, c) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                    if let Some(v) = w.get(c) {
                        to[k] = if self.abs_xyz {
                            v * scale
                        } else {
                            to[k] + v * scale
                        };
                    }
                }
                if let Some(e) = w.get(b'E') {
                    to[3] = if self.abs_e {
                        e * scale
                    } else {
                        to[3] + e * scale
                    };
                }
                if num >= 2 {
                    return self.arc(w, num == 3, to, line, sink).map(|_| true);
                }
                if to != self.pos {
                    sink(Event::Move {
                        from: self.pos,
                        to,
                        feed_mm_s: self.feed_mm_s,
                        line,
                    });
                    self.pos = to;
                }
            }
            (b'G', 4) => {
                let s = w.get(b'S').unwrap_or(0.0) + w.get(b'P').unwrap_or(0.0) / 1000.0;
                if s > 0.0 {
                    sink(Event::Dwell(s));
                }
            }
            (b'G', 20) => self.inch = true,
            (b'G', 21) => self.inch = false,
            (b'G', 90) => {
                self.abs_xyz = true;
                self.abs_e = true;
            }
            (b'G', 91) => {
                self.abs_xyz = false;
                self.abs_e = false;
            }
            (b'G', 92) => {
                let mut any = false;
                for (k, c) in [b'X', b'Y', b'Z', b'E'].into_iter().enumerate() {
                    if let Some(v) = w.get(c) {
                        self.pos[k] = v * scale;
                        any = true;
                    }
                }
                if !any {
                    self.pos = [0.0; 4];
                }
            }
            (b'G', 28) => {
                // Homing: axes named (or all) go to 0.
                let named = [b'X', b'Y', b'Z'].iter().any(|c| w.get(*c).is_some());
                for (k, c) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                    if !named || w.get(c).is_some() {
                        self.pos[k] = 0.0;
                    }
                }
            }
            (b'M', 82) => self.abs_e = true,
            (b'M', 83) => self.abs_e = false,
            (b'M', 204) => sink(Event::Accel {
                print_mm_s2: w.get(b'P').or(w.get(b'S')),
                travel_mm_s2: w.get(b'T').or(w.get(b'S')),
            }),
            _ => return Ok(false),
        }
        Ok(true)
    }

    fn comment(&self, c: &[u8], line: u32, sink: &mut dyn FnMut(Event)) {
        let c = trim(c);
        if c == b"LAYER_CHANGE" || c.starts_with(b"LAYER:") {
            sink(Event::Layer { line });
        } else if let Some(rest) = c.strip_prefix(b"Z:") {
            if let Some((z, _)) = parse_num(trim(rest)) {
                sink(Event::LayerZ(z));
            }
        }
    }
}

fn trim(b: &[u8]) -> &[u8] {
    let s = b
        .iter()
        .position(|c| !c.is_ascii_whitespace())
        .unwrap_or(b.len());
    let e = b
        .iter()
        .rposition(|c| !c.is_ascii_whitespace())
        .map_or(s, |e| e + 1);
    &b[s..e.max(s)]
}

impl GcodeReader for FastReader {
    fn read(&mut self, input: &[u8], sink: &mut dyn FnMut(Event)) -> Result<ReadCounts, ReadError> {
        let mut counts = ReadCounts::default();
        let mut line_no: u32 = 0;
        let mut start = 0usize;
        let ends = memchr::memchr_iter(b'\n', input).chain(std::iter::once(input.len()));
        for end in ends {
            let raw = &input[start..end];
            start = end + 1;
            line_no = line_no.saturating_add(1);
            if raw.is_empty() {
                continue;
            }
            counts.lines += 1;
            // Split off the comment.
            let (code, comment) = match memchr::memchr(b';', raw) {
                Some(i) => (&raw[..i], Some(&raw[i + 1..])),
                None => (raw, None),
            };
            if let Some(c) = comment {
                self.comment(c, line_no, sink);
            }
            // Strip a checksum.
            let code = match memchr::memchr(b'*', code) {
                Some(i) => &code[..i],
                None => code,
            };
            let mut words = Words::default();
            let mut cmd: Option<(u8, u32)> = None;
            let mut i = 0;
            while i < code.len() {
                let c = code[i].to_ascii_uppercase();
                if c == b' ' || c == b'\t' || c == b'\r' {
                    i += 1;
                    continue;
                }
                if c == b'(' {
                    // Parenthesised comment.
                    match code[i..].iter().position(|&b| b == b')') {
                        Some(j) => i += j + 1,
                        None => break,
                    }
                    continue;
                }
                if !c.is_ascii_uppercase() {
                    if !matches!(cmd, Some((b'G', _)) | None) {
                        break; // free text of M117 and friends
                    }
                    return Err(ReadError {
                        line: line_no,
                        msg: format!("unexpected character `{}`", c as char),
                    });
                }
                i += 1;
                let rest = &code[i..];
                // Skip spaces between letter and number (allowed by RS274).
                let skip = rest.iter().take_while(|b| **b == b' ').count();
                match parse_num(&rest[skip..]) {
                    Some((v, used)) => {
                        if cmd.is_none() && (c == b'G' || c == b'M' || c == b'T') {
                            if !(0.0..=100_000.0).contains(&v) {
                                return Err(ReadError {
                                    line: line_no,
                                    msg: format!("bad command number {v}"),
                                });
                            }
                            cmd = Some((c, v as u32));
                        } else {
                            words.set(c, v);
                        }
                        i += skip + used;
                    }
                    None => {
                        if cmd.is_some() && (c == b'X' || c == b'Y' || c == b'Z' || c == b'E') {
                            // G28 X / G92 E without a number.
                            words.set(c, 0.0);
                        } else if cmd.is_none() {
                            return Err(ReadError {
                                line: line_no,
                                msg: format!("`{}` without a number", c as char),
                            });
                        }
                    }
                }
            }
            if let Some((c, n)) = cmd {
                if c == b'N' {
                    continue;
                }
                if !self.command(c, n, &words, line_no, sink)? {
                    counts.skipped += 1;
                }
            }
        }
        Ok(counts)
    }
}

/// Reader over the firmware's own parser (`firmware::gcode::parse_line`), so the host reads
/// exactly what the printer reads. Values arrive as `f32` (the firmware's precision) and are
/// tracked in `f64`. Any line the firmware rejects is an error with its line number.
#[derive(Clone, Debug)]
pub struct FirmwareReader {
    pos: Pos4,
    abs_xyz: bool,
    abs_e: bool,
    inch: bool,
    feed_mm_s: f64,
    /// Longest chord used to expand G2/G3 arcs, mm.
    pub arc_seg_mm: f64,
}

impl Default for FirmwareReader {
    fn default() -> Self {
        FirmwareReader {
            pos: [0.0; 4],
            abs_xyz: true,
            abs_e: true,
            inch: false,
            feed_mm_s: 25.0,
            arc_seg_mm: 0.5,
        }
    }
}

impl FirmwareReader {
    fn target(&self, axes: &firmware::gcode::AxisWords) -> Pos4 {
        let scale = if self.inch { 25.4 } else { 1.0 };
        let mut to = self.pos;
        for (k, v) in axes.0.iter().enumerate().take(4) {
            if let Some(v) = v {
                let v = *v as f64 * scale;
                let abs = if k == 3 { self.abs_e } else { self.abs_xyz };
                to[k] = if abs { v } else { to[k] + v };
            }
        }
        to
    }

    fn set_feed(&mut self, f: Option<f32>) {
        if let Some(f) = f {
            let scale = if self.inch { 25.4 } else { 1.0 };
            if f > 0.0 {
                self.feed_mm_s = f as f64 * scale / 60.0;
            }
        }
    }
}

impl GcodeReader for FirmwareReader {
    fn read(&mut self, input: &[u8], sink: &mut dyn FnMut(Event)) -> Result<ReadCounts, ReadError> {
        use firmware::gcode::{parse_line, Command};
        let mut counts = ReadCounts::default();
        let mut line_no: u32 = 0;
        for raw in input.split(|&b| b == b'\n') {
            line_no = line_no.saturating_add(1);
            let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
            if raw.is_empty() {
                continue;
            }
            counts.lines += 1;
            let line = parse_line(raw).map_err(|e| ReadError {
                line: line_no,
                msg: format!("{e:?}"),
            })?;
            if let Some(c) = line.comment {
                FastReader::default().comment(c, line_no, sink);
            }
            let Some(cmd) = line.command else { continue };
            match cmd {
                Command::Move { axes, feed, .. } => {
                    self.set_feed(feed);
                    let to = self.target(&axes);
                    if to != self.pos {
                        sink(Event::Move {
                            from: self.pos,
                            to,
                            feed_mm_s: self.feed_mm_s,
                            line: line_no,
                        });
                        self.pos = to;
                    }
                }
                Command::Arc {
                    clockwise,
                    axes,
                    i,
                    j,
                    r,
                    feed,
                } => {
                    self.set_feed(feed);
                    let to = self.target(&axes);
                    let scale = if self.inch { 25.4 } else { 1.0 };
                    let ij = match (i, j) {
                        (None, None) => None,
                        (i, j) => Some((
                            i.unwrap_or(0.0) as f64 * scale,
                            j.unwrap_or(0.0) as f64 * scale,
                        )),
                    };
                    let c = arc_center(self.pos, to, ij, r.map(|r| r as f64 * scale), !clockwise)
                        .map_err(|m| ReadError {
                        line: line_no,
                        msg: m.into(),
                    })?;
                    expand_arc(
                        self.pos,
                        to,
                        c,
                        !clockwise,
                        self.arc_seg_mm,
                        self.feed_mm_s,
                        line_no,
                        sink,
                    );
                    self.pos = to;
                }
                Command::Dwell { ms, s } => {
                    let t = s.unwrap_or(0.0) as f64 + ms.unwrap_or(0.0) as f64 / 1000.0;
                    if t > 0.0 {
                        sink(Event::Dwell(t));
                    }
                }
                Command::Inches => self.inch = true,
                Command::Millimetres => self.inch = false,
                Command::Absolute => {
                    self.abs_xyz = true;
                    self.abs_e = true;
                }
                Command::Relative => {
                    self.abs_xyz = false;
                    self.abs_e = false;
                }
                Command::AbsoluteE => self.abs_e = true,
                Command::RelativeE => self.abs_e = false,
                Command::SetPosition(axes) => {
                    let scale = if self.inch { 25.4 } else { 1.0 };
                    if axes.0.iter().all(|a| a.is_none()) {
                        self.pos = [0.0; 4];
                    }
                    for (k, v) in axes.0.iter().enumerate().take(4) {
                        if let Some(v) = v {
                            self.pos[k] = *v as f64 * scale;
                        }
                    }
                }
                Command::Home(flags) => {
                    for k in 0..3 {
                        if flags.is_empty() || flags.0[k] {
                            self.pos[k] = 0.0;
                        }
                    }
                }
                Command::SetAcceleration {
                    print, travel, s, ..
                } => sink(Event::Accel {
                    print_mm_s2: print.or(s).map(f64::from),
                    travel_mm_s2: travel.or(s).map(f64::from),
                }),
                _ => counts.skipped += 1,
            }
        }
        Ok(counts)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn events(src: &str) -> Vec<Event> {
        let mut v = Vec::new();
        let r = FastReader::default().read(src.as_bytes(), &mut |e| v.push(e));
        assert!(r.is_ok(), "{r:?}");
        v
    }

    #[test]
    fn numbers() {
        assert_eq!(parse_num(b"12.5"), Some((12.5, 4)));
        assert_eq!(parse_num(b"-0.25 "), Some((-0.25, 5)));
        assert_eq!(parse_num(b".5"), Some((0.5, 2)));
        assert_eq!(parse_num(b"-"), None);
        assert_eq!(parse_num(b"x"), None);
    }

    #[test]
    fn modes_and_layers() {
        let ev = events(
            "G90\nM83\nG1 X10 Y0 E1 F600\n;LAYER_CHANGE\n;Z:0.4\nG1 X20 E1\nG91\nG1 X-5\nG92 E0\n",
        );
        let moves: Vec<_> = ev
            .iter()
            .filter_map(|e| match e {
                Event::Move { to, .. } => Some(*to),
                _ => None,
            })
            .collect();
        assert_eq!(moves[0], [10.0, 0.0, 0.0, 1.0]);
        assert_eq!(moves[1], [20.0, 0.0, 0.0, 2.0]);
        assert_eq!(moves[2], [15.0, 0.0, 0.0, 2.0]);
        assert!(ev.contains(&Event::LayerZ(0.4)));
        assert!(ev.iter().any(|e| matches!(e, Event::Layer { line: 4 })));
    }

    #[test]
    fn arcs_expand() {
        let ev = events("G0 X10 Y0\nG3 X0 Y10 I-10 J0 F600\n");
        let n = ev
            .iter()
            .filter(|e| matches!(e, Event::Move { .. }))
            .count();
        assert!(n > 10);
        if let Some(Event::Move { to, .. }) = ev.last() {
            assert!((to[0]).abs() < 1e-9 && (to[1] - 10.0).abs() < 1e-9);
        }
    }

    #[test]
    fn garbage_is_an_error_with_line() {
        let mut r = FastReader::default();
        let e = r.read(b"G1 X1\nG1 X#\n", &mut |_| {});
        assert_eq!(e.err().map(|e| e.line), Some(2));
        let e = FastReader::default().read(b"G1 F-5 X1\n", &mut |_| {});
        assert!(e.is_err());
    }
}
