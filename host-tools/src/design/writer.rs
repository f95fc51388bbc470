//! G-code writer: turns a [`Model`] into G-code for a [`Profile`].
//!
//! - E per string = cross-section × length ÷ filament area; the running E total is kept in
//!   `f64` and written rounded, relative E being the difference of rounded totals, so rounding
//!   never drifts.
//! - Only axes whose rounded value changed are written; `F` only when it changes.
//! - Travels are `G0` without `E` (never an `E0` travel under absolute E); travels at least
//!   `retraction.min_travel_mm` long retract and prime.
//! - Arc strings become `G2`/`G3` (with `Z` for helical arcs).
//! - Markers become `;LAYER_CHANGE`, `;Z:`, `;HEIGHT:` — once per helix turn for layer-free
//!   prints, so a layer pause stops at a turn boundary. `;TYPE:` for feature types.
//! - Emission thinning ([`crate::design::model::EmissionHints`]) merges short consecutive strings,
//!   keeping their volume and time (the globe's poles).

use crate::design::model::{Model, StateChange, Step, Str};
use crate::design::profile::{
    filament_area_mm2, EMode, Markers, Profile, Retraction, TemplateValues,
};
use glam::DVec3;
use std::io::Write;

/// Options of one write.
#[derive(Clone, Debug, Default)]
pub struct WriteOptions {
    /// Leave out the profile's start and end code (golden tests, fragments).
    pub bare: bool,
    /// Header comment written first (e.g. the source file name).
    pub header: Option<String>,
}

/// What a write produced.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WriteSummary {
    /// Strings written (after thinning).
    pub strings: usize,
    /// Strings merged away by thinning.
    pub thinned: usize,
    /// Travels written.
    pub travels: usize,
    /// Retractions written.
    pub retractions: usize,
    /// Layer/turn markers written.
    pub markers: usize,
    /// Filament pushed, mm.
    pub filament_mm: f64,
    /// Extruded volume, mm³.
    pub volume_mm3: f64,
    /// Bytes written.
    pub bytes: usize,
}

/// Why a model could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// A step carries a value that cannot be printed.
    #[error("step {index}: {msg}")]
    BadStep {
        /// Index in `model.steps`.
        index: usize,
        /// What is wrong.
        msg: String,
    },
    /// The output failed.
    #[error("writing G-code: {0}")]
    Io(#[from] std::io::Error),
}

/// `v.round() as i64` (half away from zero, saturating, NaN → 0) without the libm call that
/// `f64::round` becomes on baseline x86-64: the cast truncates, and `v - trunc(v)` is exact.
#[inline]
pub fn round_i64(v: f64) -> i64 {
    let t = v as i64;
    let f = v - t as f64;
    if f >= 0.5 {
        t.saturating_add(1)
    } else if f <= -0.5 {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// Appends `v` with at most `decimals` decimals, trailing zeros trimmed ("1.5", "-0.25", "3").
pub fn push_fixed(buf: &mut Vec<u8>, v: f64, decimals: u32) {
    let scale = 10i64.pow(decimals);
    let n = round_i64(v * scale as f64);
    push_scaled(buf, n, decimals);
}

/// Two ASCII digits of every number 0..100.
const DIGITS2: &[u8; 200] = b"0001020304050607080910111213141516171819\
2021222324252627282930313233343536373839\
4041424344454647484950515253545556575859\
6061626364656667686970717273747576777879\
8081828384858687888990919293949596979899";

/// Writes the decimal digits of `v` right-aligned ending at `end` of `dst`; returns the
/// first index. `dst` must have room (20 digits at most).
#[inline]
fn digits_into(dst: &mut [u8], mut end: usize, mut v: u64) -> usize {
    while v >= 100 {
        let d = (v % 100) as usize * 2;
        v /= 100;
        end -= 2;
        dst[end] = DIGITS2[d];
        dst[end + 1] = DIGITS2[d + 1];
    }
    if v >= 10 {
        let d = v as usize * 2;
        end -= 2;
        dst[end] = DIGITS2[d];
        dst[end + 1] = DIGITS2[d + 1];
    } else {
        end -= 1;
        dst[end] = b'0' + v as u8;
    }
    end
}

/// Number of decimal digits of `v` (1 for 0).
#[inline]
fn digit_count(mut v: u64) -> usize {
    let mut n = 1;
    while v >= 100 {
        v /= 100;
        n += 2;
    }
    n + usize::from(v >= 10)
}

/// Opens `WIDTH` bytes at the end of `buf` (one constant-size store) for a number to be
/// written in place; the caller cuts it back to the number's length. Writing the digits
/// straight into the output avoids copying them from a stack buffer just written byte by
/// byte (a store-forwarding stall per number in profiles).
#[inline]
fn open_slot<const WIDTH: usize>(buf: &mut Vec<u8>) -> usize {
    let old = buf.len();
    buf.extend_from_slice(&[b'0'; WIDTH]);
    old
}

/// Appends the integer `n` scaled by 10^-`decimals` (trailing zeros trimmed): the whole
/// number is formatted on the stack, two digits at a time, and appended in one copy. The
/// usual decimal counts get their own copy with a constant divisor (a multiplication instead
/// of a 64-bit division per number).
#[inline]
fn push_scaled(buf: &mut Vec<u8>, n: i64, decimals: u32) {
    match decimals {
        0 => push_scaled_const::<0>(buf, n),
        1 => push_scaled_const::<1>(buf, n),
        2 => push_scaled_const::<2>(buf, n),
        3 => push_milli(buf, n),
        4 => push_scaled_const::<4>(buf, n),
        5 => push_scaled_const::<5>(buf, n),
        _ => push_scaled_with(buf, n, decimals.min(18), 10u64.pow(decimals.min(18))),
    }
}

/// `.xyz` of every thousandth 0..1000 with trailing zeros (and, for 0, the point) trimmed:
/// (length, bytes).
const MILLI: [(u8, [u8; 4]); 1000] = {
    let mut t = [(0u8, [0u8; 4]); 1000];
    let mut k = 1;
    while k < 1000 {
        let d = [(k / 100) as u8, (k / 10 % 10) as u8, (k % 10) as u8];
        let len = if d[2] != 0 {
            4
        } else if d[1] != 0 {
            3
        } else {
            2
        };
        t[k] = (len, [b'.', b'0' + d[0], b'0' + d[1], b'0' + d[2]]);
        k += 1;
    }
    t
};

/// `push_scaled(buf, n, 3)`, the writer's usual case (millimetres to the micrometre): the
/// integer part two digits at a time, the fraction from a table, written in place.
#[inline]
fn push_milli(buf: &mut Vec<u8>, n: i64) {
    let a = n.unsigned_abs();
    let int = a / 1000;
    if int >= 10_000 {
        return push_scaled_const::<3>(buf, n);
    }
    let old = open_slot::<16>(buf);
    let dst = &mut buf[old..];
    let mut i = 0;
    if n < 0 {
        dst[0] = b'-';
        i = 1;
    }
    let int = int as usize;
    if int >= 100 {
        let hi = if int >= 1000 {
            dst[i] = b'0' + (int / 1000) as u8;
            i += 1;
            int / 100 % 10
        } else {
            int / 100
        };
        dst[i] = b'0' + hi as u8;
        let lo = int % 100 * 2;
        dst[i + 1] = DIGITS2[lo];
        dst[i + 2] = DIGITS2[lo + 1];
        i += 3;
    } else if int >= 10 {
        dst[i] = DIGITS2[int * 2];
        dst[i + 1] = DIGITS2[int * 2 + 1];
        i += 2;
    } else {
        dst[i] = b'0' + int as u8;
        i += 1;
    }
    let (len, frac) = MILLI[(a % 1000) as usize];
    dst[i..i + 4].copy_from_slice(&frac);
    i += len as usize;
    buf.truncate(old + i);
}

#[inline]
fn push_scaled_const<const D: u32>(buf: &mut Vec<u8>, n: i64) {
    push_scaled_with(buf, n, D, const { 10u64.pow(D) })
}

/// `push_scaled` for `scale` = 10^`decimals` (`decimals` ≤ 18), written in place.
#[inline(always)]
fn push_scaled_with(buf: &mut Vec<u8>, n: i64, decimals: u32, scale: u64) {
    let a = n.unsigned_abs();
    let (int, mut frac) = (a / scale, a % scale);
    let mut d = decimals as usize;
    if frac == 0 {
        d = 0;
    } else {
        while frac % 10 == 0 {
            frac /= 10;
            d -= 1;
        }
    }
    let len = usize::from(n < 0) + digit_count(int) + if d > 0 { d + 1 } else { 0 };
    // Sign + 20 integer digits + point + 18 decimals fit in 48.
    let old = open_slot::<48>(buf);
    let dst = &mut buf[old..];
    let mut end = len;
    if d > 0 {
        // The fraction's leading zeros are the slot's '0's.
        digits_into(dst, end, frac);
        end -= d + 1;
        dst[end] = b'.';
    }
    digits_into(dst, end, int);
    if n < 0 {
        dst[0] = b'-';
    }
    buf.truncate(old + len);
}

fn push_u64(buf: &mut Vec<u8>, v: u64) {
    let len = digit_count(v);
    let old = open_slot::<24>(buf);
    digits_into(&mut buf[old..], len, v);
    buf.truncate(old + len);
}

/// The G-code writer for one profile.
#[derive(Clone, Debug)]
pub struct GcodeWriter<'p> {
    profile: &'p Profile,
    opts: WriteOptions,
}

struct State {
    /// Last written position in integer units of 10^-decimals mm; `None` = unknown.
    pos: [Option<i64>; 3],
    /// Exact position (for travel lengths).
    pos_f: Option<DVec3>,
    /// Running E total (exact).
    e_total: f64,
    /// Last written rounded E total (integer units).
    e_written: i64,
    /// Current feed in 0.1 mm/min units.
    f: Option<i64>,
    area: f64,
    retracted: bool,
    /// Retraction in force (the profile's until a design's `StateChange::Retraction`).
    retraction: Retraction,
}

impl<'p> GcodeWriter<'p> {
    /// A writer for `profile`.
    pub fn new(profile: &'p Profile, opts: WriteOptions) -> Self {
        GcodeWriter { profile, opts }
    }

    /// Writes the model to a string.
    pub fn to_string(&self, model: &Model) -> Result<(String, WriteSummary), WriteError> {
        let mut buf = Vec::with_capacity(model.steps.len() * 40 + 1024);
        let summary = self.write_into(model, &mut buf)?;
        // Only ASCII and the model's own comments (valid UTF-8) are written.
        let s = String::from_utf8(buf).map_err(|e| WriteError::BadStep {
            index: 0,
            msg: format!("non-UTF-8 output: {e}"),
        })?;
        Ok((s, summary))
    }

    /// Writes the model to `out`.
    pub fn write<W: Write>(&self, model: &Model, mut out: W) -> Result<WriteSummary, WriteError> {
        let mut buf = Vec::with_capacity(model.steps.len() * 40 + 1024);
        let summary = self.write_into(model, &mut buf)?;
        out.write_all(&buf)?;
        Ok(summary)
    }

    /// Writes the model into a byte buffer (the fast path the benchmarks measure).
    pub fn write_into(&self, model: &Model, buf: &mut Vec<u8>) -> Result<WriteSummary, WriteError> {
        validate(model)?;
        let steps = &model.steps;
        let p = self.profile;
        let dec = p.decimals;
        let scale = 10f64.powi(dec as i32);
        let mut sum = WriteSummary::default();
        let start_len = buf.len();
        // About 28 bytes per string (the globe: 1.5 MB for 45,000): one allocation.
        buf.reserve(steps.len() * 30 + 4096);

        // Temperatures set before the first string feed the start code instead of being
        // written twice.
        let mut hotend_c = p.hotend_c;
        let mut bed_c = p.bed_c;
        for s in steps {
            match s {
                Step::String(_) | Step::Travel { .. } => break,
                Step::State(StateChange::HotendTemp { celsius, .. }) => hotend_c = *celsius,
                Step::State(StateChange::BedTemp { celsius, .. }) => bed_c = *celsius,
                _ => {}
            }
        }
        if let Some(h) = &self.opts.header {
            for line in h.lines() {
                buf.extend_from_slice(b"; ");
                buf.extend_from_slice(line.as_bytes());
                buf.push(b'\n');
            }
        }
        // Profile-chosen framing (design::profile): Cura's header, start code with its
        // placeholders, the fan from layer `fan_off_layers`, M73 progress (design::progress).
        let tv = TemplateValues {
            hotend_c,
            bed_c,
            top_z_mm: (!self.opts.bare).then(|| model.bbox().max.z),
        };
        let mut progress_at: Vec<usize> = Vec::new();
        let progress = p.progress && !self.opts.bare;
        if !self.opts.bare {
            if p.markers == Markers::Cura {
                let layers = steps
                    .iter()
                    .filter(|s| matches!(s, Step::Marker { .. }))
                    .count();
                buf.extend_from_slice(b";FLAVOR:Marlin\n;LAYER_COUNT:");
                push_u64(buf, layers as u64);
                buf.push(b'\n');
            }
            buf.extend_from_slice(p.fill(&p.gcode.start, &tv).as_bytes());
            if !buf.ends_with(b"\n") {
                buf.push(b'\n');
            }
            if p.fan > 0.0 && p.fan_off_layers == 0 {
                push_fan(buf, p.fan);
            }
        }
        let body_start = buf.len();
        if progress {
            progress_at.push(body_start);
        }
        buf.extend_from_slice(match p.e_mode {
            EMode::Absolute => b"M82\nG92 E0\n",
            EMode::Relative => b"M83\nG92 E0\n",
        });

        let mut st = State {
            pos: [None; 3],
            pos_f: None,
            e_total: 0.0,
            e_written: 0,
            f: None,
            area: p.filament_area_mm2(),
            retracted: false,
            retraction: p.retraction,
        };
        // Thinning merges strings on the fly (no second copy of the model).
        let mut emission = Emission::new(steps, model.emission.thin_min_len_mm);
        let mut motion_seen = false;
        for item in emission.by_ref() {
            let step = match item {
                Item::Str(s, len) => {
                    motion_seen = true;
                    self.emit_string(buf, &mut st, &s, Some(len), scale, &mut sum);
                    continue;
                }
                Item::Ref(s, len) => {
                    motion_seen = true;
                    self.emit_string(buf, &mut st, s, Some(len), scale, &mut sum);
                    continue;
                }
                Item::Step(step) => step,
            };
            match step {
                Step::String(s) => {
                    motion_seen = true;
                    self.emit_string(buf, &mut st, s, None, scale, &mut sum);
                }
                Step::Travel { to, speed_mm_s } => {
                    motion_seen = true;
                    let to_i = quant(*to, scale);
                    if st.pos.iter().zip(to_i).any(|(a, b)| *a != Some(b)) {
                        self.travel(buf, &mut st, *to, *speed_mm_s, scale, &mut sum);
                    }
                }
                Step::Comment(c) => {
                    for line in c.lines() {
                        buf.extend_from_slice(b"; ");
                        buf.extend_from_slice(line.as_bytes());
                        buf.push(b'\n');
                    }
                }
                Step::Marker {
                    z_mm, height_mm, ..
                } => {
                    match p.markers {
                        Markers::Prusa => {
                            buf.extend_from_slice(b";LAYER_CHANGE\n;Z:");
                            push_fixed(buf, *z_mm, dec);
                            buf.extend_from_slice(b"\n;HEIGHT:");
                            push_fixed(buf, *height_mm, dec);
                            buf.push(b'\n');
                        }
                        Markers::Cura => {
                            buf.extend_from_slice(b";LAYER:");
                            push_u64(buf, sum.markers as u64);
                            buf.push(b'\n');
                        }
                    }
                    sum.markers += 1;
                    if progress {
                        progress_at.push(buf.len());
                    }
                    if !self.opts.bare
                        && p.fan > 0.0
                        && sum.markers == p.fan_off_layers as usize + 1
                        && p.fan_off_layers > 0
                    {
                        push_fan(buf, p.fan);
                    }
                }
                Step::Type(t) => {
                    buf.extend_from_slice(b";TYPE:");
                    buf.extend_from_slice(t.lines().next().unwrap_or("").as_bytes());
                    buf.push(b'\n');
                }
                Step::State(sc) => {
                    if !motion_seen
                        && !self.opts.bare
                        && matches!(
                            sc,
                            StateChange::HotendTemp { .. } | StateChange::BedTemp { .. }
                        )
                    {
                        continue; // already in the start code
                    }
                    if let StateChange::Retraction(r) = sc {
                        // Prime with the old length before the new one applies.
                        if st.retracted {
                            self.retract(buf, &mut st, scale, false);
                        }
                        st.retraction = *r;
                        continue;
                    }
                    write_state(buf, &mut st, sc, dec);
                }
            }
        }
        sum.thinned = emission.consumed_strings - sum.strings;
        sum.filament_mm = st.e_total;
        if progress {
            progress_at.push(buf.len());
        }
        if !self.opts.bare {
            buf.extend_from_slice(p.fill(&p.gcode.end, &tv).as_bytes());
            if !buf.ends_with(b"\n") {
                buf.push(b'\n');
            }
        }
        if progress {
            crate::design::progress::insert_m73(buf, body_start, &progress_at, p)?;
        }
        sum.bytes = buf.len() - start_len;
        Ok(sum)
    }

    /// A string, reached by a travel when it does not start where the head is.
    fn emit_string(
        &self,
        buf: &mut Vec<u8>,
        st: &mut State,
        s: &Str,
        len: Option<f64>,
        scale: f64,
        sum: &mut WriteSummary,
    ) {
        let start_i = quant(s.start, scale);
        if st.pos.iter().zip(start_i).any(|(a, b)| *a != Some(b)) {
            self.travel(buf, st, s.start, None, scale, sum);
        }
        let len = self.string(buf, st, s, len, scale);
        sum.strings += 1;
        sum.volume_mm3 += s.cross_mm2 * len;
    }

    fn push_f(&self, buf: &mut Vec<u8>, st: &mut State, speed_mm_s: f64) {
        let f = round_i64(speed_mm_s * 600.0); // 0.1 mm/min
        if st.f != Some(f) {
            buf.extend_from_slice(b" F");
            push_scaled(buf, f, 1);
            st.f = Some(f);
        }
    }

    fn push_axes(&self, buf: &mut Vec<u8>, st: &mut State, to: DVec3, scale: f64) -> bool {
        let q = quant(to, scale);
        let mut any = false;
        for (k, name) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if st.pos[k] != Some(q[k]) {
                buf.push(b' ');
                buf.push(name);
                push_scaled(buf, q[k], self.profile.decimals);
                st.pos[k] = Some(q[k]);
                any = true;
            }
        }
        st.pos_f = Some(to);
        any
    }

    fn push_e(&self, buf: &mut Vec<u8>, st: &mut State, scale: f64) {
        let e_i = round_i64(st.e_total * scale);
        let v = match self.profile.e_mode {
            EMode::Absolute => e_i,
            EMode::Relative => e_i - st.e_written,
        };
        st.e_written = e_i;
        buf.extend_from_slice(b" E");
        push_scaled(buf, v, self.profile.decimals);
    }

    fn travel(
        &self,
        buf: &mut Vec<u8>,
        st: &mut State,
        to: DVec3,
        speed: Option<f64>,
        scale: f64,
        sum: &mut WriteSummary,
    ) {
        let p = self.profile;
        let dist = st.pos_f.map(|f| f.distance(to)).unwrap_or(f64::INFINITY);
        let retract = st.retraction.length_mm > 0.0
            && st.pos_f.is_some()
            && st.e_total > 0.0
            && !st.retracted
            && dist >= st.retraction.min_travel_mm;
        if retract {
            self.retract(buf, st, scale, true);
            sum.retractions += 1;
        }
        buf.extend_from_slice(b"G0");
        self.push_f(buf, st, speed.unwrap_or(p.travel_speed_mm_s));
        self.push_axes(buf, st, to, scale);
        buf.push(b'\n');
        sum.travels += 1;
    }

    fn retract(&self, buf: &mut Vec<u8>, st: &mut State, scale: f64, pull: bool) {
        let p = self.profile;
        let r = round_i64(st.retraction.length_mm * scale);
        buf.extend_from_slice(b"G1");
        self.push_f(buf, st, st.retraction.speed_mm_s);
        buf.extend_from_slice(b" E");
        match (p.e_mode, pull) {
            (EMode::Absolute, true) => push_scaled(buf, st.e_written - r, p.decimals),
            (EMode::Absolute, false) => push_scaled(buf, st.e_written, p.decimals),
            (EMode::Relative, true) => push_scaled(buf, -r, p.decimals),
            (EMode::Relative, false) => push_scaled(buf, r, p.decimals),
        }
        buf.push(b'\n');
        st.retracted = pull;
    }

    /// Writes one string (`len`: its length when already known); returns its length, mm.
    fn string(
        &self,
        buf: &mut Vec<u8>,
        st: &mut State,
        s: &Str,
        len: Option<f64>,
        scale: f64,
    ) -> f64 {
        if st.retracted {
            self.retract(buf, st, scale, false);
        }
        let len = len.unwrap_or_else(|| s.len_mm());
        st.e_total += s.cross_mm2 * len / st.area;
        match s.arc {
            Some(a) => {
                buf.extend_from_slice(if a.ccw { b"G3" } else { b"G2" });
                let from = st.pos_f.unwrap_or(s.start);
                // Full circles keep X/Y unchanged; Marlin treats that as 360°.
                self.push_axes(buf, st, s.end, scale);
                buf.extend_from_slice(b" I");
                push_fixed(buf, a.center_xy[0] - from.x, self.profile.decimals);
                buf.extend_from_slice(b" J");
                push_fixed(buf, a.center_xy[1] - from.y, self.profile.decimals);
                self.push_e(buf, st, scale);
                self.push_f(buf, st, s.speed_mm_s);
            }
            None => {
                buf.extend_from_slice(b"G1");
                let moved = self.push_axes(buf, st, s.end, scale);
                if !moved {
                    // Shorter than the output resolution: drop the line, its E carries over.
                    buf.truncate(buf.len() - 2);
                    return len;
                }
                self.push_e(buf, st, scale);
                self.push_f(buf, st, s.speed_mm_s);
            }
        }
        buf.push(b'\n');
        len
    }
}

/// `M106 S<duty × 255>`: the part fan on at the profile's duty.
fn push_fan(buf: &mut Vec<u8>, duty: f64) {
    buf.extend_from_slice(b"M106 S");
    push_u64(buf, (duty * 255.0).round() as u64);
    buf.push(b'\n');
}

fn write_state(buf: &mut Vec<u8>, st: &mut State, sc: &StateChange, dec: u32) {
    match sc {
        StateChange::HotendTemp { celsius, wait } => {
            buf.extend_from_slice(if *wait { b"M109 S" } else { b"M104 S" });
            push_fixed(buf, *celsius, 1);
        }
        StateChange::BedTemp { celsius, wait } => {
            buf.extend_from_slice(if *wait { b"M190 S" } else { b"M140 S" });
            push_fixed(buf, *celsius, 1);
        }
        StateChange::Fan(duty) => {
            let d = duty.clamp(0.0, 1.0);
            if d == 0.0 {
                buf.extend_from_slice(b"M107");
            } else {
                buf.extend_from_slice(b"M106 S");
                push_u64(buf, (d * 255.0).round() as u64);
            }
        }
        StateChange::FilamentDiameter(d) => {
            st.area = filament_area_mm2(*d);
            buf.extend_from_slice(b"; filament diameter ");
            push_fixed(buf, *d, dec);
        }
        StateChange::Gcode(text) => {
            for line in text.lines().map(str::trim).filter(|l| !l.is_empty()) {
                buf.extend_from_slice(line.as_bytes());
                buf.push(b'\n');
            }
            return;
        }
        StateChange::Pause { now } => {
            buf.extend_from_slice(if *now { b"M601 S1" } else { b"M601" });
        }
        StateChange::Retraction(_) => return, // applied by the caller
    }
    buf.push(b'\n');
}

#[inline]
fn quant(p: DVec3, scale: f64) -> [i64; 3] {
    [
        round_i64(p.x * scale),
        round_i64(p.y * scale),
        round_i64(p.z * scale),
    ]
}

/// Rejects values that cannot become G-code (non-finite points, non-positive speeds, negative
/// cross-sections or filament diameters).
pub fn validate(model: &Model) -> Result<(), WriteError> {
    let bad = |index: usize, msg: String| Err(WriteError::BadStep { index, msg });
    for (i, s) in model.steps.iter().enumerate() {
        match s {
            Step::String(s) => {
                if !(s.start.is_finite() && s.end.is_finite()) {
                    return bad(i, format!("non-finite point {:?} → {:?}", s.start, s.end));
                }
                if !(s.cross_mm2.is_finite() && s.cross_mm2 >= 0.0) {
                    return bad(i, format!("cross-section {} mm² is invalid", s.cross_mm2));
                }
                if !(s.speed_mm_s.is_finite() && s.speed_mm_s > 0.0) {
                    return bad(i, format!("speed {} mm/s is invalid", s.speed_mm_s));
                }
                if let Some(a) = s.arc {
                    if !(a.center_xy[0].is_finite() && a.center_xy[1].is_finite()) {
                        return bad(i, "non-finite arc centre".into());
                    }
                }
            }
            Step::Travel { to, speed_mm_s } => {
                if !to.is_finite() {
                    return bad(i, format!("non-finite travel target {to:?}"));
                }
                if let Some(v) = speed_mm_s {
                    if !(v.is_finite() && *v > 0.0) {
                        return bad(i, format!("travel speed {v} mm/s is invalid"));
                    }
                }
            }
            Step::Marker {
                z_mm, height_mm, ..
            } => {
                if !(z_mm.is_finite() && height_mm.is_finite()) {
                    return bad(i, "non-finite marker height".into());
                }
            }
            Step::State(StateChange::FilamentDiameter(d)) => {
                if !(d.is_finite() && *d > 0.0) {
                    return bad(i, format!("filament diameter {d} mm is invalid"));
                }
            }
            Step::State(StateChange::HotendTemp { celsius, .. })
            | Step::State(StateChange::BedTemp { celsius, .. }) => {
                if !(celsius.is_finite() && (0.0..=400.0).contains(celsius)) {
                    return bad(i, format!("temperature {celsius} °C is out of range"));
                }
            }
            Step::State(StateChange::Fan(d)) => {
                if !d.is_finite() {
                    return bad(i, "non-finite fan duty".into());
                }
            }
            Step::State(StateChange::Retraction(r)) => {
                let ok = |v: f64| v.is_finite() && v >= 0.0;
                if !(ok(r.length_mm) && ok(r.min_travel_mm) && r.speed_mm_s.is_finite())
                    || r.speed_mm_s <= 0.0
                {
                    return bad(i, format!("retraction {r:?} is invalid"));
                }
            }
            Step::State(StateChange::Gcode(g)) => {
                if g.chars()
                    .any(|c| !(c.is_ascii_graphic() || c == ' ' || c == '\n'))
                {
                    return bad(i, format!("raw G-code {g:?}: only printable ASCII lines"));
                }
            }
            Step::State(StateChange::Pause { .. }) => {}
            Step::Comment(_) | Step::Type(_) => {}
        }
    }
    Ok(())
}

/// Emission thinning: merges runs of contiguous straight strings until each merged string is
/// at least `min_len_mm` long. The merged string keeps the run's volume (cross-section =
/// volume ÷ chord) and its time (speed = chord ÷ Σ time).
pub fn thin(steps: &[Step], min_len_mm: f64) -> Vec<Step> {
    Emission::new(steps, Some(min_len_mm))
        .map(|item| match item {
            Item::Str(s, _) => Step::String(s),
            Item::Ref(s, _) => Step::String(*s),
            Item::Step(s) => s.clone(),
        })
        .collect()
}

/// A run of short strings being merged (the first one by reference: no copy per string).
struct Acc<'a> {
    first: &'a Str,
    end: DVec3,
    volume: f64,
    time: f64,
    len: f64,
    n: usize,
}

impl<'a> Acc<'a> {
    fn new(st: &'a Str) -> Self {
        let l = st.len_mm();
        Acc {
            first: st,
            end: st.end,
            volume: st.cross_mm2 * l,
            time: l / st.speed_mm_s,
            len: l,
            n: 1,
        }
    }

    /// The merged string (or the run's only one) and its length (`Str::len_mm` of it,
    /// computed once).
    fn finish(self) -> Item<'a> {
        if self.n == 1 {
            return Item::Ref(self.first, self.len);
        }
        let start = self.first.start;
        let chord = start.distance(self.end);
        if chord <= 1e-9 || self.time <= 0.0 {
            return Item::Ref(self.first, self.first.len_mm());
        }
        Item::Str(
            Str::line(start, self.end, self.volume / chord, chord / self.time),
            chord,
        )
    }
}

/// One step as written: a merged string with its length, a string of the model with its
/// length, or any other step of the model.
enum Item<'a> {
    Str(Str, f64),
    Ref(&'a Str, f64),
    Step(&'a Step),
}

/// The model's steps in emission order, thinned on the fly when `min_len_mm` is given.
struct Emission<'a> {
    steps: std::slice::Iter<'a, Step>,
    min_len_mm: Option<f64>,
    acc: Option<Acc<'a>>,
    /// A step that ended a run, given out after the run's merged string.
    held: Option<&'a Step>,
    /// Strings of the model consumed so far.
    consumed_strings: usize,
}

impl<'a> Emission<'a> {
    fn new(steps: &'a [Step], min_len_mm: Option<f64>) -> Self {
        Emission {
            steps: steps.iter(),
            min_len_mm,
            acc: None,
            held: None,
            consumed_strings: 0,
        }
    }
}

impl<'a> Iterator for Emission<'a> {
    type Item = Item<'a>;

    fn next(&mut self) -> Option<Item<'a>> {
        if let Some(h) = self.held.take() {
            return Some(Item::Step(h));
        }
        loop {
            let Some(step) = self.steps.next() else {
                return self.acc.take().map(Acc::finish);
            };
            if let Step::String(_) = step {
                self.consumed_strings += 1;
            }
            let min = match (step, self.min_len_mm) {
                (Step::String(st), Some(min)) if st.arc.is_none() => min,
                _ => {
                    // Any other step ends a run.
                    return match self.acc.take() {
                        Some(a) => {
                            self.held = Some(step);
                            Some(a.finish())
                        }
                        None => Some(Item::Step(step)),
                    };
                }
            };
            let Step::String(st) = step else {
                continue;
            };
            if let Some(a) = &mut self.acc {
                if a.len < min && a.end.distance_squared(st.start) < 1e-12 {
                    let l = st.len_mm();
                    a.end = st.end;
                    a.volume += st.cross_mm2 * l;
                    a.time += l / st.speed_mm_s;
                    a.len += l;
                    a.n += 1;
                    continue;
                }
            }
            let done = self.acc.replace(Acc::new(st));
            if let Some(a) = done {
                return Some(a.finish());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_formatting() {
        let cases = [
            (1.5, "1.5"),
            (-0.25, "-0.25"),
            (3.0, "3"),
            (0.0004, "0"),
            (-0.0004, "0"),
            (12.3456, "12.346"),
            (100.0, "100"),
        ];
        for (v, s) in cases {
            let mut b = Vec::new();
            push_fixed(&mut b, v, 3);
            assert_eq!(String::from_utf8(b).unwrap_or_default(), s, "{v}");
        }
    }

    /// The reference: `format!` of the integer and fraction parts, trailing zeros trimmed.
    fn reference(n: i64, decimals: u32) -> String {
        if decimals == 0 {
            return n.to_string();
        }
        let scale = 10u64.pow(decimals);
        let a = n.unsigned_abs();
        let frac = format!("{:0w$}", a % scale, w = decimals as usize);
        let frac = frac.trim_end_matches('0');
        let sign = if n < 0 { "-" } else { "" };
        if frac.is_empty() {
            format!("{sign}{}", a / scale)
        } else {
            format!("{sign}{}.{frac}", a / scale)
        }
    }

    fn scaled(n: i64, d: u32) -> String {
        let mut b = Vec::new();
        push_scaled(&mut b, n, d);
        String::from_utf8(b).unwrap_or_default()
    }

    #[test]
    fn scaled_edges() {
        for (n, d) in [
            (0, 3),
            (5, 3),
            (-5, 3),
            (1000, 3),
            (-1000, 3),
            (1234567, 3),
            (10, 1),
            (i64::MAX, 3),
            (i64::MIN, 3),
            (i64::MIN, 0),
            (99, 0),
            (100, 0),
            (1, 6),
            (9_999_999, 3),
            (10_000_000, 3),
            (-9_999_999, 3),
            (-10_000_000, 3),
            (999, 3),
            (-1, 3),
            (100_010, 3),
        ] {
            assert_eq!(scaled(n, d), reference(n, d), "{n} {d}");
        }
    }

    proptest::proptest! {
        #[test]
        fn scaled_matches_format(n in proptest::num::i64::ANY, d in 0u32..=6) {
            proptest::prop_assert_eq!(scaled(n, d), reference(n, d));
        }

        #[test]
        fn milli_matches_format(n in -20_000_000i64..20_000_000) {
            proptest::prop_assert_eq!(scaled(n, 3), reference(n, 3));
        }

        #[test]
        fn small_scaled_matches_format(n in -10_000_000i64..10_000_000, d in 0u32..=6) {
            proptest::prop_assert_eq!(scaled(n, d), reference(n, d));
        }

        #[test]
        fn round_matches_std(v in proptest::num::f64::ANY) {
            proptest::prop_assert_eq!(round_i64(v), v.round() as i64);
        }

        #[test]
        fn round_matches_std_near_halves(k in -1_000_000_000i64..1_000_000_000, e in -3i32..3) {
            // Exact and nearly exact halves, where rounding modes differ.
            let v = k as f64 * 0.5;
            for w in [v, v.next_up(), v.next_down()] {
                proptest::prop_assert_eq!(round_i64(w), w.round() as i64, "{}", w);
                let x = w * 10f64.powi(e);
                proptest::prop_assert_eq!(round_i64(x), x.round() as i64, "{}", x);
            }
        }

        #[test]
        fn fixed_matches_format_away_from_ties(v in -10_000.0f64..10_000.0) {
            // `format!` rounds the exact binary value; we round v × 1000 — they agree unless
            // v × 1000 is within rounding noise of a tie.
            let x = v * 1000.0;
            proptest::prop_assume!((x - x.trunc()).abs() - 0.5 < -1e-6 || (x - x.trunc()).abs() - 0.5 > 1e-6);
            let mut b = Vec::new();
            push_fixed(&mut b, v, 3);
            let want = format!("{v:.3}");
            let want = want.trim_end_matches('0').trim_end_matches('.');
            let want = if want == "-0" { "0" } else { want };
            proptest::prop_assert_eq!(String::from_utf8(b).unwrap_or_default(), want);
        }
    }

    #[test]
    fn thinning_keeps_volume_and_time() {
        let mut steps = Vec::new();
        for i in 0..10 {
            let a = DVec3::new(i as f64 * 0.1, 0.0, 0.0);
            let b = DVec3::new((i + 1) as f64 * 0.1, 0.0, 0.0);
            let v = if i % 2 == 0 { 10.0 } else { 13.0 };
            steps.push(Step::String(Str::line(a, b, 0.2, v)));
        }
        let t = thin(&steps, 0.5);
        let strs: Vec<&Str> = t
            .iter()
            .filter_map(|s| match s {
                Step::String(s) => Some(s),
                _ => None,
            })
            .collect();
        assert_eq!(strs.len(), 2);
        let vol: f64 = strs.iter().map(|s| s.volume_mm3()).sum();
        assert!((vol - 0.2).abs() < 1e-9);
        let time: f64 = strs.iter().map(|s| s.len_mm() / s.speed_mm_s).sum();
        let t0: f64 = (0..10)
            .map(|i| 0.1 / if i % 2 == 0 { 10.0 } else { 13.0 })
            .sum();
        assert!((time - t0).abs() < 1e-9);
    }
}
