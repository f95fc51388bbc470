//! The moves and their extrusion math: strings as `G1`/`G2`/`G3` with E from cross-section ×
//! length ÷ filament area (rounded totals, so rounding never drifts), travels as `G0` with
//! retraction and prime, feed and axes written only when they change, and state changes.

use super::numbers::{push_fixed, push_scaled, push_u64, round_i64};
use super::{GcodeWriter, State, WriteSummary};
use crate::design::model::{StateChange, Str};
use crate::design::profile::{filament_area_mm2, EMode};
use glam::DVec3;

impl<'p> GcodeWriter<'p> {
    /// A string, reached by a travel when it does not start where the head is.
    pub(super) fn emit_string(
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
            self.travel(buf, st, s.start, None, 0.0, scale, sum);
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
        let (v, written) = match self.profile.e_mode {
            EMode::Absolute => (e_i + st.e_shift, e_i + st.e_shift),
            EMode::Relative => (e_i - st.e_written, e_i),
        };
        st.e_written = written;
        buf.extend_from_slice(b" E");
        push_scaled(buf, v, self.profile.decimals);
    }

    /// A travel to `to`; `then_mm`: the length of the travels that follow it directly (a
    /// lift's across and down), which count for the retraction.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn travel(
        &self,
        buf: &mut Vec<u8>,
        st: &mut State,
        to: DVec3,
        speed: Option<f64>,
        then_mm: f64,
        scale: f64,
        sum: &mut WriteSummary,
    ) {
        let dist = st
            .pos_f
            .map(|f| f.distance(to) + then_mm)
            .unwrap_or(f64::INFINITY);
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
        self.push_f(buf, st, speed.unwrap_or(st.travel_speed_mm_s));
        self.push_axes(buf, st, to, scale);
        buf.push(b'\n');
        sum.travels += 1;
    }

    pub(super) fn retract(&self, buf: &mut Vec<u8>, st: &mut State, scale: f64, pull: bool) {
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

pub(super) fn write_state(buf: &mut Vec<u8>, st: &mut State, sc: &StateChange, dec: u32) {
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
        StateChange::Bead(m) => {
            if st.bead == *m {
                return;
            }
            st.bead = *m;
            buf.push(b';');
            buf.extend_from_slice(m.comment().as_bytes());
        }
        // Applied by the caller.
        StateChange::Retraction(_) | StateChange::TravelSpeed(_) | StateChange::Primer(_) => return,
    }
    buf.push(b'\n');
}

#[inline]
pub(super) fn quant(p: DVec3, scale: f64) -> [i64; 3] {
    [
        round_i64(p.x * scale),
        round_i64(p.y * scale),
        round_i64(p.z * scale),
    ]
}
