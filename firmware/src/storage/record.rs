//! The settings record: every value M500 saves, its valid range, and its byte layout.
//!
//! Layout (little-endian), format [`FORMAT_VERSION`]:
//!
//! ```text
//! u16 format version │ u16 body length │ body │ u32 CRC-32 (ISO-HDLC) of everything before it
//! body = steps/mm[X Y Z E] │ max feed mm/s[4] │ max accel mm/s²[4] │ accel print, retract,
//!        travel mm/s² │ junction deviation mm │ home offset mm[X Y Z] │ hotend PID │ bed PID │
//!        pause: retract mm, retract feed mm/s, lift mm, park X, park Y mm, park feed mm/s,
//!        speed-up ×, max flow mm³/s, segment mm │ driver current mA[4] (u16)
//!        │ microsteps[4] (u16, M350) │ u8 stealthChop bits X=0..E=3 (M569)   ← format 2
//! PID = u8 (1 = PID, 0 = bang-bang) │ f32 Kp │ f32 Ki │ f32 Kd (zeros for bang-bang)
//! ```
//!
//! Format 2 added M350 and M569 (Marlin saves M569's mode; it does not save microsteps, but
//! here steps/mm scale with them, so saved steps/mm without their microsteps would be wrong).
//! A format-1 record still loads: the two new fields take the build's factory values.
//!
//! Every `f32` is stored as its bits, so a load gives back exactly what was saved. A record
//! whose CRC, version or length does not match, or whose values are out of range, is refused
//! as a whole ([`RecordError`]): the caller falls back to the factory defaults.

use crate::config::{MachineConfig, PauseConfig};
use crate::motion::AXES;
use crate::thermal::pid::PidGains;

/// Version of the byte layout. Any change of the layout or of a value's meaning bumps it; a
/// store of another version loads the factory defaults (there is no migration yet).
pub const FORMAT_VERSION: u16 = 2;

/// Bytes of the body of format 1 (still read: see the module documentation).
pub const BODY_LEN_V1: usize = 4 * AXES * 3 + 4 * 4 + 4 * 3 + 13 * 2 + 4 * 9 + 2 * AXES;

/// Bytes of the body of format 2.
pub const BODY_LEN: usize = BODY_LEN_V1 + 2 * AXES + 1;

/// Bytes of a whole record (header, body, CRC).
pub const RECORD_LEN: usize = 4 + BODY_LEN + 4;

use crate::ranges::{
    Bound, ACCEL, DRIVER_CURRENT, HOME_OFFSET, JUNCTION_DEVIATION, MAX_FEED, PARK_FEED, PARK_XY,
    PAUSE_LIFT, PAUSE_RETRACT, PID_GAIN, RETRACT_FEED, SEGMENT, SPEEDUP, STEPS_PER_MM, VOLUMETRIC,
};

/// Factory default RMS current of every driver, mA (Marlin's `X_CURRENT` default, 800 mA).
pub const DEFAULT_DRIVER_CURRENT_MA: u16 = 800;

/// Everything M500 saves and M501 loads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// M92 X Y Z E.
    pub steps_per_mm: [f32; AXES],
    /// M203 X Y Z E, mm/s.
    pub max_feed_mm_s: [f32; AXES],
    /// M201 X Y Z E, mm/s².
    pub max_accel_mm_s2: [f32; AXES],
    /// M204 P, mm/s².
    pub accel_print_mm_s2: f32,
    /// M204 R, mm/s².
    pub accel_retract_mm_s2: f32,
    /// M204 T, mm/s².
    pub accel_travel_mm_s2: f32,
    /// M205 J, mm.
    pub junction_deviation_mm: f32,
    /// M206 X Y Z, mm.
    pub home_offset_mm: [f32; 3],
    /// M301 (None: the hotend runs bang-bang).
    pub hotend_pid: Option<PidGains>,
    /// M304 (None: the bed runs bang-bang).
    pub bed_pid: Option<PidGains>,
    /// M760.
    pub pause: PauseConfig,
    /// M906 X Y Z E, mA.
    pub driver_current_ma: [u16; AXES],
    /// M350 X Y Z E: microsteps per full step (1, 2, 4, ..., 256).
    pub microsteps: [u16; AXES],
    /// M569 X Y Z E: stealthChop (true) or spreadCycle.
    pub stealthchop: [bool; AXES],
}

/// Why a stored record was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// Fewer bytes than a header and a CRC, or a body length that does not match the bytes.
    Truncated,
    /// The CRC does not match: the bytes were damaged.
    BadCrc,
    /// Written by a firmware with another layout.
    Version(u16),
    /// The body length does not match this version's.
    Length(u16),
    /// A value is outside its range (its name).
    OutOfRange(&'static str),
}

impl core::fmt::Display for RecordError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RecordError::Truncated => f.write_str("record truncated"),
            RecordError::BadCrc => f.write_str("record checksum mismatch"),
            RecordError::Version(v) => write!(
                f,
                "record format {v}, this firmware reads format {FORMAT_VERSION}"
            ),
            RecordError::Length(n) => write!(f, "record body of {n} bytes, expected {BODY_LEN}"),
            RecordError::OutOfRange(what) => write!(f, "{what} out of range"),
        }
    }
}

impl Settings {
    /// The settings a machine configuration and heater gains stand for (factory defaults when
    /// given the build's configuration).
    pub fn from_config(
        cfg: &MachineConfig,
        hotend_pid: Option<PidGains>,
        bed_pid: Option<PidGains>,
    ) -> Self {
        Settings {
            steps_per_mm: cfg.axes.map(|a| a.steps_per_mm),
            max_feed_mm_s: cfg.axes.map(|a| a.max_feed_mm_s),
            max_accel_mm_s2: cfg.axes.map(|a| a.max_accel_mm_s2),
            accel_print_mm_s2: cfg.accel_print_mm_s2,
            accel_retract_mm_s2: cfg.accel_retract_mm_s2,
            accel_travel_mm_s2: cfg.accel_travel_mm_s2,
            junction_deviation_mm: cfg.junction_deviation_mm,
            home_offset_mm: cfg.home_offset_mm,
            hotend_pid,
            bed_pid,
            pause: cfg.pause,
            driver_current_ma: cfg.driver_current_ma,
            microsteps: cfg.axes.map(|a| a.microsteps),
            stealthchop: cfg.driver_stealthchop,
        }
    }

    /// Write these settings into a machine configuration (the heater gains are the caller's).
    pub fn apply_to(&self, cfg: &mut MachineConfig) {
        for (i, a) in cfg.axes.iter_mut().enumerate() {
            a.steps_per_mm = self.steps_per_mm[i];
            a.max_feed_mm_s = self.max_feed_mm_s[i];
            a.max_accel_mm_s2 = self.max_accel_mm_s2[i];
            // The saved steps/mm are at these microsteps: set both, no scaling.
            a.microsteps = self.microsteps[i];
        }
        cfg.driver_stealthchop = self.stealthchop;
        cfg.accel_print_mm_s2 = self.accel_print_mm_s2;
        cfg.accel_retract_mm_s2 = self.accel_retract_mm_s2;
        cfg.accel_travel_mm_s2 = self.accel_travel_mm_s2;
        cfg.junction_deviation_mm = self.junction_deviation_mm;
        cfg.home_offset_mm = self.home_offset_mm;
        cfg.pause = self.pause;
        cfg.driver_current_ma = self.driver_current_ma;
    }

    /// Check every value against its [`Bound`]; the first one out of range is named.
    pub fn validate(&self) -> Result<(), RecordError> {
        let check = |b: &Bound, vs: &[f32]| {
            if vs.iter().all(|v| b.contains(*v)) {
                Ok(())
            } else {
                Err(RecordError::OutOfRange(b.name))
            }
        };
        check(&STEPS_PER_MM, &self.steps_per_mm)?;
        check(&MAX_FEED, &self.max_feed_mm_s)?;
        check(&ACCEL, &self.max_accel_mm_s2)?;
        check(
            &ACCEL,
            &[
                self.accel_print_mm_s2,
                self.accel_retract_mm_s2,
                self.accel_travel_mm_s2,
            ],
        )?;
        check(&JUNCTION_DEVIATION, &[self.junction_deviation_mm])?;
        check(&HOME_OFFSET, &self.home_offset_mm)?;
        for g in [self.hotend_pid, self.bed_pid].into_iter().flatten() {
            check(&PID_GAIN, &[g.kp, g.ki, g.kd])?;
        }
        let p = &self.pause;
        check(&PAUSE_RETRACT, &[p.retract_mm])?;
        check(&RETRACT_FEED, &[p.retract_feed_mm_s])?;
        check(&PAUSE_LIFT, &[p.lift_z_mm])?;
        check(&PARK_XY, &[p.park_x_mm, p.park_y_mm])?;
        check(&PARK_FEED, &[p.park_feed_mm_s])?;
        check(&SPEEDUP, &[p.speedup_factor])?;
        check(&VOLUMETRIC, &[p.max_volumetric_mm3_s])?;
        check(&SEGMENT, &[p.segment_len_mm])?;
        let currents = self.driver_current_ma.map(f32::from);
        check(&DRIVER_CURRENT, &currents)?;
        if self
            .microsteps
            .iter()
            .all(|m| m.is_power_of_two() && *m <= 256)
        {
            Ok(())
        } else {
            Err(RecordError::OutOfRange("microsteps"))
        }
    }

    /// The record's bytes.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        let mut w = Writer {
            buf: [0; RECORD_LEN],
            at: 0,
        };
        w.u16(FORMAT_VERSION);
        w.u16(BODY_LEN as u16);
        for arr in [self.steps_per_mm, self.max_feed_mm_s, self.max_accel_mm_s2] {
            arr.iter().for_each(|v| w.f32(*v));
        }
        w.f32(self.accel_print_mm_s2);
        w.f32(self.accel_retract_mm_s2);
        w.f32(self.accel_travel_mm_s2);
        w.f32(self.junction_deviation_mm);
        self.home_offset_mm.iter().for_each(|v| w.f32(*v));
        for pid in [self.hotend_pid, self.bed_pid] {
            w.u8(u8::from(pid.is_some()));
            let g = pid.unwrap_or(PidGains {
                kp: 0.0,
                ki: 0.0,
                kd: 0.0,
            });
            w.f32(g.kp);
            w.f32(g.ki);
            w.f32(g.kd);
        }
        let p = &self.pause;
        for v in [
            p.retract_mm,
            p.retract_feed_mm_s,
            p.lift_z_mm,
            p.park_x_mm,
            p.park_y_mm,
            p.park_feed_mm_s,
            p.speedup_factor,
            p.max_volumetric_mm3_s,
            p.segment_len_mm,
        ] {
            w.f32(v);
        }
        self.driver_current_ma.iter().for_each(|v| w.u16(*v));
        self.microsteps.iter().for_each(|v| w.u16(*v));
        w.u8(self
            .stealthchop
            .iter()
            .enumerate()
            .fold(0, |b, (i, on)| b | u8::from(*on) << i));
        let crc = super::crc::crc32(&w.buf[..RECORD_LEN - 4]);
        w.u32(crc);
        w.buf
    }

    /// Read a record, checking its CRC, version, length and every value's range. A format-1
    /// record loads with the microsteps and driver modes of `MachineConfig::ENDER3` (the
    /// build's factory values).
    pub fn decode(bytes: &[u8]) -> Result<Settings, RecordError> {
        let v1 = bytes.len() >= 2 && u16::from_le_bytes([bytes[0], bytes[1]]) == 1;
        let body = if v1 {
            checked_body(bytes, 1, BODY_LEN_V1)?
        } else {
            checked_body(bytes, FORMAT_VERSION, BODY_LEN)?
        };
        let mut r = Reader { buf: body, at: 0 };
        let mut arr = || [r.f32(), r.f32(), r.f32(), r.f32()];
        let steps_per_mm = arr();
        let max_feed_mm_s = arr();
        let max_accel_mm_s2 = arr();
        let accel_print_mm_s2 = r.f32();
        let accel_retract_mm_s2 = r.f32();
        let accel_travel_mm_s2 = r.f32();
        let junction_deviation_mm = r.f32();
        let home_offset_mm = [r.f32(), r.f32(), r.f32()];
        let mut pid = || {
            let on = r.u8();
            let g = PidGains {
                kp: r.f32(),
                ki: r.f32(),
                kd: r.f32(),
            };
            match on {
                0 => Ok(None),
                1 => Ok(Some(g)),
                _ => Err(RecordError::OutOfRange("PID flag")),
            }
        };
        let hotend_pid = pid()?;
        let bed_pid = pid()?;
        let pause = PauseConfig {
            retract_mm: r.f32(),
            retract_feed_mm_s: r.f32(),
            lift_z_mm: r.f32(),
            park_x_mm: r.f32(),
            park_y_mm: r.f32(),
            park_feed_mm_s: r.f32(),
            speedup_factor: r.f32(),
            max_volumetric_mm3_s: r.f32(),
            segment_len_mm: r.f32(),
        };
        let driver_current_ma = [r.u16(), r.u16(), r.u16(), r.u16()];
        let factory = MachineConfig::ENDER3;
        let (microsteps, stealthchop) = if v1 {
            (
                factory.axes.map(|a| a.microsteps),
                factory.driver_stealthchop,
            )
        } else {
            let m = [r.u16(), r.u16(), r.u16(), r.u16()];
            let bits = r.u8();
            if bits & !0b1111 != 0 {
                return Err(RecordError::OutOfRange("driver modes"));
            }
            (m, core::array::from_fn(|i| bits & (1 << i) != 0))
        };
        let s = Settings {
            steps_per_mm,
            max_feed_mm_s,
            max_accel_mm_s2,
            accel_print_mm_s2,
            accel_retract_mm_s2,
            accel_travel_mm_s2,
            junction_deviation_mm,
            home_offset_mm,
            hotend_pid,
            bed_pid,
            pause,
            driver_current_ma,
            microsteps,
            stealthchop,
        };
        s.validate()?;
        Ok(s)
    }
}

/// Check a record's framing (length, CRC, version, body length) and return its body.
pub(crate) fn checked_body(
    bytes: &[u8],
    version: u16,
    body_len: usize,
) -> Result<&[u8], RecordError> {
    let n = bytes.len();
    if n < 8 {
        return Err(RecordError::Truncated);
    }
    let (framed, crc) = bytes.split_at(n - 4);
    let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if super::crc::crc32(framed) != stored {
        return Err(RecordError::BadCrc);
    }
    let v = u16::from_le_bytes([framed[0], framed[1]]);
    if v != version {
        return Err(RecordError::Version(v));
    }
    let len = u16::from_le_bytes([framed[2], framed[3]]);
    if usize::from(len) != body_len {
        return Err(RecordError::Length(len));
    }
    let body = &framed[4..];
    if body.len() != body_len {
        return Err(RecordError::Truncated);
    }
    Ok(body)
}

/// Little-endian writer into a fixed array (sized exactly by the layout constants).
pub(crate) struct Writer<const N: usize> {
    pub(crate) buf: [u8; N],
    pub(crate) at: usize,
}

impl<const N: usize> Writer<N> {
    pub(crate) fn put(&mut self, b: &[u8]) {
        if let Some(d) = self.buf.get_mut(self.at..self.at + b.len()) {
            d.copy_from_slice(b);
        }
        self.at += b.len();
    }
    pub(crate) fn u8(&mut self, v: u8) {
        self.put(&[v]);
    }
    pub(crate) fn u16(&mut self, v: u16) {
        self.put(&v.to_le_bytes());
    }
    pub(crate) fn u32(&mut self, v: u32) {
        self.put(&v.to_le_bytes());
    }
    pub(crate) fn f32(&mut self, v: f32) {
        self.put(&v.to_bits().to_le_bytes());
    }
}

/// Little-endian reader of a body whose length was checked (a short body reads zeros).
pub(crate) struct Reader<'a> {
    pub(crate) buf: &'a [u8],
    pub(crate) at: usize,
}

impl Reader<'_> {
    pub(crate) fn take<const K: usize>(&mut self) -> [u8; K] {
        let mut out = [0; K];
        if let Some(s) = self.buf.get(self.at..self.at + K) {
            out.copy_from_slice(s);
        }
        self.at += K;
        out
    }
    pub(crate) fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    pub(crate) fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.take())
    }
    pub(crate) fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    pub(crate) fn f32(&mut self) -> f32 {
        f32::from_bits(self.u32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::thermal::{Control, ThermalConfig};

    fn factory() -> Settings {
        let pid = |c: Control| match c {
            Control::Pid(g) => Some(g),
            Control::BangBang { .. } => None,
        };
        let t = ThermalConfig::ENDER3;
        Settings::from_config(
            &MachineConfig::ENDER3,
            pid(t.hotend.control),
            pid(t.bed.control),
        )
    }

    #[test]
    fn factory_defaults_are_in_range_and_round_trip_to_the_bit() {
        let s = factory();
        s.validate().unwrap();
        assert_eq!(Settings::decode(&s.encode()), Ok(s));
        let mut odd = s;
        odd.steps_per_mm[3] = 93.123_45;
        odd.junction_deviation_mm = 0.0123;
        odd.bed_pid = Some(PidGains {
            kp: 1.5,
            ki: 0.25,
            kd: 99.0,
        });
        odd.driver_current_ma = [580, 580, 650, 1100];
        assert_eq!(Settings::decode(&odd.encode()), Ok(odd));
    }

    #[test]
    fn every_damaged_byte_is_caught_by_the_crc() {
        let bytes = factory().encode();
        for i in 0..bytes.len() {
            for bit in [0x01u8, 0x80] {
                let mut b = bytes;
                b[i] ^= bit;
                assert!(Settings::decode(&b).is_err(), "byte {i} bit {bit:#x}");
            }
        }
        assert_eq!(
            Settings::decode(&bytes[..bytes.len() - 1]),
            Err(RecordError::BadCrc)
        );
        assert_eq!(Settings::decode(&[]), Err(RecordError::Truncated));
    }

    /// A format-1 record (written by the firmware before M350/M569 were saved) loads, the new
    /// fields at the factory values. The bytes are built here by the format-1 layout: the
    /// format-2 record without its last 9 body bytes, version 1, its own CRC.
    #[test]
    fn a_format_1_record_loads_with_the_new_fields_at_their_defaults() {
        let mut s = factory();
        s.steps_per_mm[3] = 97.5;
        s.microsteps = [32, 32, 8, 64];
        s.stealthchop = [false, true, false, true];
        let v2 = s.encode();
        let mut v1 = Vec::new();
        v1.extend_from_slice(&1u16.to_le_bytes());
        v1.extend_from_slice(&(BODY_LEN_V1 as u16).to_le_bytes());
        v1.extend_from_slice(&v2[4..4 + BODY_LEN_V1]);
        let crc = crate::storage::crc32(&v1);
        v1.extend_from_slice(&crc.to_le_bytes());
        let got = Settings::decode(&v1).unwrap();
        let mut want = s;
        want.microsteps = factory().microsteps;
        want.stealthchop = factory().stealthchop;
        assert_eq!(got, want);
        // Format 2 keeps them.
        assert_eq!(Settings::decode(&v2), Ok(s));
        let mut bad = s;
        bad.microsteps[1] = 12;
        assert_eq!(
            Settings::decode(&bad.encode()),
            Err(RecordError::OutOfRange("microsteps"))
        );
    }

    #[test]
    fn another_version_is_refused_even_with_a_good_crc() {
        let mut b = factory().encode();
        b[0] = 0;
        let crc = crate::storage::crc32(&b[..RECORD_LEN - 4]);
        b[RECORD_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(Settings::decode(&b), Err(RecordError::Version(0)));
    }

    #[test]
    fn an_out_of_range_value_refuses_the_record() {
        let mut s = factory();
        s.steps_per_mm[0] = f32::NAN;
        assert_eq!(
            Settings::decode(&s.encode()),
            Err(RecordError::OutOfRange("steps/mm"))
        );
        let mut s = factory();
        s.junction_deviation_mm = 0.5;
        assert_eq!(
            Settings::decode(&s.encode()),
            Err(RecordError::OutOfRange("junction deviation"))
        );
    }
}
