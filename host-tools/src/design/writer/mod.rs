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
//!
//! This module frames the output (header, start and end code, markers, M73 progress) and
//! walks the steps; `moves` writes each move and state change, `numbers` formats the numbers,
//! `emission` orders and thins the steps, `validate` refuses what cannot be printed.

use crate::design::model::{Model, StateChange, Step};
use crate::design::profile::{EMode, Markers, Primer, Profile, Retraction, TemplateValues};
use crate::design::raw::RawTracker;
use glam::DVec3;
use std::io::Write;

mod emission;
mod moves;
mod numbers;
mod validate;

pub use emission::thin;
pub use numbers::{push_fixed, round_i64};
pub use validate::{speeds, validate};

use emission::{Emission, Item};
use moves::{quant, write_state};
use numbers::push_u64;

// The unit tests below also reach these.
#[cfg(test)]
use crate::design::model::Str;
#[cfg(test)]
use numbers::push_scaled;

/// Comment written after the printer's start code, before the design (not in `bare` output):
/// tools that take the design out of a job (`timebased`, `cure-check`) start here, so what the
/// design prints before its first layer mark (a prime line, a floor ring) is the design's.
pub const DESIGN_BEGIN: &str = ";DESIGN_BEGIN";
/// Comment written after the design, before the printer's end code (not in `bare` output).
pub const DESIGN_END: &str = ";DESIGN_END";

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
    /// Last written E (integer units): the absolute E word, or the rounded total the next
    /// relative E word is measured from.
    e_written: i64,
    /// Absolute E: written E = rounded total + this (raw lines that move or set E shift it).
    e_shift: i64,
    /// Current feed in 0.1 mm/min units.
    f: Option<i64>,
    area: f64,
    retracted: bool,
    /// Retraction in force (the profile's until a design's `StateChange::Retraction`).
    retraction: Retraction,
    /// Speed of travels without their own, mm/s (the profile's until a design's
    /// `StateChange::TravelSpeed`).
    travel_speed_mm_s: f64,
    /// Bead model declared so far (the 3D page's default until the design declares one).
    bead: crate::gcode::bead::AreaModel,
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
        let p = self.profile;
        speeds(model, p)?;
        let steps = &model.steps;
        let dec = p.decimals;
        let scale = 10f64.powi(dec as i32);
        let mut sum = WriteSummary::default();
        let start_len = buf.len();
        // About 28 bytes per string (the globe: 1.5 MB for 45,000): one allocation.
        buf.reserve(steps.len() * 30 + 4096);

        // The design's state is final, the profile's a default: temperatures set before the
        // first move feed the start code instead of being written twice, the primer chosen
        // there decides the start code's purge, and a fan set there replaces the profile's.
        let lead = lead_in(steps);
        let layer_z = print_heights(steps);
        let hotend_c = lead.hotend_c.unwrap_or(p.hotend_c);
        let bed_c = lead.bed_c.unwrap_or(p.bed_c);
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
            primer: lead.primer,
        };
        // The profile's fan comes on (after the start code or at its layer) only while the
        // design has not set the fan itself.
        let mut fan_set = lead.fan;
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
            if p.fan > 0.0 && p.fan_off_layers == 0 && !fan_set {
                push_fan(buf, p.fan);
            }
            buf.extend_from_slice(DESIGN_BEGIN.as_bytes());
            buf.push(b'\n');
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
            e_shift: 0,
            f: None,
            area: p.filament_area_mm2(),
            retracted: false,
            retraction: p.retraction,
            travel_speed_mm_s: p.travel_speed_mm_s,
            bead: crate::gcode::bead::AreaModel::Rectangle,
        };
        // Thinning merges strings on the fly (no second copy of the model).
        let mut emission = Emission::new(steps, model.emission.thin_min_len_mm);
        let mut motion_seen = false;
        while let Some(item) = emission.next() {
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
                        // A lift (up, across, down) is one travel for the retraction: it
                        // retracts before it rises, not after.
                        let then_mm = travel_run_mm(*to, emission.rest());
                        self.travel(buf, &mut st, *to, *speed_mm_s, then_mm, scale, &mut sum);
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
                            push_fixed(
                                buf,
                                layer_z.get(sum.markers).copied().unwrap_or(*z_mm),
                                dec,
                            );
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
                        && !fan_set
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
                    match sc {
                        StateChange::Retraction(r) => {
                            // Prime with the old length before the new one applies.
                            if st.retracted {
                                self.retract(buf, &mut st, scale, false);
                            }
                            st.retraction = *r;
                        }
                        StateChange::TravelSpeed(v) => st.travel_speed_mm_s = *v,
                        StateChange::Primer(_) => {} // decided the start code
                        StateChange::Gcode(text) => {
                            write_state(buf, &mut st, sc, dec);
                            fan_set |= self.follow_raw(buf, &mut st, text, scale);
                        }
                        StateChange::Fan(_) => {
                            fan_set = true;
                            write_state(buf, &mut st, sc, dec);
                        }
                        _ => write_state(buf, &mut st, sc, dec),
                    }
                }
            }
        }
        sum.thinned = emission.consumed_strings - sum.strings;
        sum.filament_mm = st.e_total;
        if progress {
            progress_at.push(buf.len());
        }
        if !self.opts.bare {
            buf.extend_from_slice(DESIGN_END.as_bytes());
            buf.push(b'\n');
            buf.extend_from_slice(p.fill(&p.gcode.end, &tv).as_bytes());
            if !buf.ends_with(b"\n") {
                buf.push(b'\n');
            }
        }
        if progress {
            crate::design::progress::insert_m73(buf, body_start, &progress_at, p).map_err(|e| {
                WriteError::BadStep {
                    index: 0,
                    msg: format!("progress estimate: the written G-code does not read back: {e}"),
                }
            })?;
        }
        sum.bytes = buf.len() - start_len;
        Ok(sum)
    }
}

/// The height each marker's layer prints at, in marker order: where the first string after
/// it (before the next marker) starts — a turtle's `mark_layer` records the pen's Z, which is
/// still the layer below until the next string climbs (the `;Z:` of `fc_speed_lattice` was one
/// layer behind) — else the marker's own Z. (A design's string starts on its layer: a helical
/// arc's whole turn is one string; the G-code reader's rule for moves that come onto a layer,
/// `motion::layer_height_of`, gives the same height for the G-code written here.)
fn print_heights(steps: &[Step]) -> Vec<f64> {
    let mut out = Vec::new();
    let mut open = false;
    for s in steps {
        match s {
            Step::Marker { z_mm, .. } => {
                out.push(*z_mm);
                open = true;
            }
            Step::String(st) if open => {
                if let Some(z) = out.last_mut() {
                    *z = st.start.z;
                }
                open = false;
            }
            _ => {}
        }
    }
    out
}

/// What a design sets before its first move: the start code's temperatures and primer, and
/// whether it sets the fan itself.
struct LeadIn {
    hotend_c: Option<f64>,
    bed_c: Option<f64>,
    primer: Primer,
    fan: bool,
}

fn lead_in(steps: &[Step]) -> LeadIn {
    let mut l = LeadIn {
        hotend_c: None,
        bed_c: None,
        primer: Primer::Profile,
        fan: false,
    };
    for s in steps {
        match s {
            Step::String(_) | Step::Travel { .. } => break,
            Step::State(StateChange::HotendTemp { celsius, .. }) => l.hotend_c = Some(*celsius),
            Step::State(StateChange::BedTemp { celsius, .. }) => l.bed_c = Some(*celsius),
            Step::State(StateChange::Primer(p)) => l.primer = *p,
            Step::State(StateChange::Fan(_)) => l.fan = true,
            Step::State(StateChange::Gcode(g)) => {
                l.fan |= RawTracker::new([None; 3], 0.0, true, DVec3::ZERO)
                    .apply(g)
                    .fan
            }
            _ => {}
        }
    }
    l
}

impl GcodeWriter<'_> {
    /// After raw lines: the position, feed and E they leave (the writer continues from
    /// there, see `design::raw`). Returns true when they set the fan.
    fn follow_raw(&self, buf: &mut Vec<u8>, st: &mut State, text: &str, scale: f64) -> bool {
        let abs_e = self.profile.e_mode == EMode::Absolute;
        let pos = st
            .pos_f
            .map_or([None; 3], |p| [Some(p.x), Some(p.y), Some(p.z)]);
        let mut t = RawTracker::new(pos, st.e_written as f64 / scale, abs_e, DVec3::ZERO);
        let fx = t.apply(text);
        if fx.modes {
            // Marlin's G90/G91 switch E as well: the profile's E mode again.
            buf.extend_from_slice(if abs_e { b"M82\n" } else { b"M83\n" });
        }
        if fx.moved {
            st.pos_f = t.position();
            st.pos = match st.pos_f {
                Some(p) => quant(p, scale).map(Some),
                None => [None; 3],
            };
        }
        if fx.feed {
            st.f = None;
        }
        if fx.e_changed && abs_e {
            // Later E words continue from the E the raw lines left.
            let e_i = numbers::round_i64(t.e_mm * scale);
            st.e_shift = e_i - numbers::round_i64(st.e_total * scale);
            st.e_written = e_i;
        }
        fx.fan
    }
}

/// Length of the travels that follow a travel ending at `from` directly (state changes and
/// comments between them do not break the run), mm.
fn travel_run_mm(from: DVec3, rest: &[Step]) -> f64 {
    let (mut at, mut len) = (from, 0.0);
    for s in rest {
        match s {
            Step::Travel { to, .. } => {
                len += at.distance(*to);
                at = *to;
            }
            Step::State(_) | Step::Comment(_) | Step::Type(_) => {}
            Step::String(_) | Step::Marker { .. } => break,
        }
    }
    len
}

/// `M106 S<duty × 255>`: the part fan on at the profile's duty.
fn push_fan(buf: &mut Vec<u8>, duty: f64) {
    buf.extend_from_slice(b"M106 S");
    push_u64(buf, (duty * 255.0).round() as u64);
    buf.push(b'\n');
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
