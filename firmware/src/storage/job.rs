//! The paused-job record: what a job parked at a layer boundary needs to continue after a
//! power cut (issue 13, "a pause that survives a power cut"). Saved once the layer pause has
//! parked, cleared when the job resumes or ends; kept under its own key in the same store as
//! the settings, with the same framing (format version, body length, CRC-32).
//!
//! Layout (little-endian), format [`JOB_FORMAT_VERSION`]:
//!
//! ```text
//! u16 version │ u16 body length │ body │ u32 CRC-32
//! body = u8 source kind (1 host, 2 SD file) │ u32 host line or SD byte offset │
//!        u8 path length │ [u8; JOB_PATH_CAP] path (zero padded) │
//!        u32 layer │ i32 boundary Z µm │ i32 boundary steps[X Y Z E] │ i32 park steps[X Y Z E] │
//!        u8 flags (bit 0 relative XYZ, 1 relative E, 2 inches, 3 G10-retracted) │
//!        f32 feed mm/s │ f32 feed % │ f32 flow % │ f64 G92 offset mm[X Y Z] │ f64 logical E mm │
//!        f64 commanded machine position mm[X Y Z E] │
//!        f32 pause retract mm │ f32 hotend target °C │ f32 bed target °C │ u8 fan PWM │
//!        u32 SD file size (0 for a host job)
//! ```
//!
//! Format 3 added the SD file's size (M1000 refuses a file whose size changed since: another
//! file under the same name). A format-2 record, whose body is format 3's without the size,
//! still loads when it is a host job (the firmware that wrote format 2 kept no SD jobs; an SD
//! record of format 2 is refused: its file could not be checked).
//!
//! Format 2 added the commanded machine position and widened the offsets to `f64` (the
//! interpreter's own precision), so a resumed job computes every later step exactly as the
//! uninterrupted one. A format-1 record (no firmware released with it resumes jobs) is refused
//! as another version: the job is announced as unusable, never resumed from a guess.

use super::record::{checked_body, Reader, RecordError, Writer};
use crate::motion::{StepPos, AXES};

/// Version of the job record's layout.
pub const JOB_FORMAT_VERSION: u16 = 3;

/// Longest SD-card path kept (bytes, UTF-8): a directory and a long file name.
pub const JOB_PATH_CAP: usize = 96;

/// Bytes of the body of format 2.
const JOB_BODY_LEN_V2: usize =
    1 + 4 + 1 + JOB_PATH_CAP + 4 + 4 + 4 * AXES * 2 + 1 + 4 * 3 + 8 * 3 + 8 + 8 * AXES + 4 * 3 + 1;

/// Bytes of the body of format 3 (format 2's and the SD file size).
pub const JOB_BODY_LEN: usize = JOB_BODY_LEN_V2 + 4;

/// Bytes of a whole job record.
pub const JOB_RECORD_LEN: usize = 4 + JOB_BODY_LEN + 4;

/// Where the job comes from, and where in it the boundary is.
#[derive(Clone, Debug, PartialEq)]
pub enum JobSource {
    /// Streamed by a host: the line number (`N…`) of the first line after the boundary (the
    /// line that started the new layer); the host restarts from it.
    Host {
        /// Line number to restart from.
        line: u32,
    },
    /// Read from the SD card: the file and the byte offset of the first line after the
    /// boundary.
    Sd {
        /// Path on the card (UTF-8, at most [`JOB_PATH_CAP`] bytes).
        path: heapless::String<JOB_PATH_CAP>,
        /// Byte offset to continue from.
        offset: u32,
        /// The file's size, bytes (a file of another size under the same name is not it).
        size: u32,
    },
}

/// The modal G-code state at the boundary (what [`crate::machine::MachineState`] reports).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModalState {
    /// G91 (X Y Z relative).
    pub relative_xyz: bool,
    /// M83 (E relative).
    pub relative_e: bool,
    /// G20 (inches).
    pub inches: bool,
    /// G10 has retracted and no G11 followed.
    pub retracted: bool,
    /// Modal feed, mm/s (before the override).
    pub feed_mm_s: f32,
    /// M220 feed override, %.
    pub feed_pct: f32,
    /// M221 flow override, %.
    pub flow_pct: f32,
    /// G92 offsets X Y Z (machine = logical + offset), mm.
    pub offset_mm: [f64; 3],
    /// The logical E position (what G92 E and absolute E words refer to), mm.
    pub logical_e_mm: f64,
    /// The commanded machine position X Y Z (machine coordinates) and E (filament fed, flow
    /// applied), mm: exact, where the steps are rounded (relative moves add to it).
    pub machine_mm: [f64; AXES],
}

/// A job parked at a layer boundary.
#[derive(Clone, Debug, PartialEq)]
pub struct PausedJob {
    /// The job and its position.
    pub source: JobSource,
    /// The layer about to start (the boundary is before it).
    pub layer: u32,
    /// Height of the layer that starts at the boundary, µm (the layer detector's height for
    /// the mark; the boundary position's Z when the job gave none).
    pub boundary_z_um: i32,
    /// Where the head stopped at the boundary, steps (X Y Z E).
    pub boundary_steps: StepPos,
    /// Where it is parked, steps (after retract, lift and park).
    pub park_steps: StepPos,
    /// Modal state at the boundary.
    pub modal: ModalState,
    /// Filament the pause retracted, mm (primed again on resume).
    pub retract_mm: f32,
    /// Hotend target before the pause, °C.
    pub hotend_c: f32,
    /// Bed target, °C.
    pub bed_c: f32,
    /// Part-cooling fan PWM, 0–255.
    pub fan_pwm: u8,
}

impl PausedJob {
    /// The record's bytes.
    pub fn encode(&self) -> [u8; JOB_RECORD_LEN] {
        let mut w = Writer {
            buf: [0; JOB_RECORD_LEN],
            at: 0,
        };
        w.u16(JOB_FORMAT_VERSION);
        w.u16(JOB_BODY_LEN as u16);
        let mut path = [0u8; JOB_PATH_CAP];
        let mut size = 0;
        match &self.source {
            JobSource::Host { line } => {
                w.u8(1);
                w.u32(*line);
                w.u8(0);
            }
            JobSource::Sd {
                path: p,
                offset,
                size: s,
            } => {
                size = *s;
                w.u8(2);
                w.u32(*offset);
                let b = p.as_bytes();
                path[..b.len()].copy_from_slice(b);
                w.u8(b.len() as u8);
            }
        }
        w.put(&path);
        w.u32(self.layer);
        w.u32(self.boundary_z_um as u32);
        for v in self.boundary_steps.iter().chain(self.park_steps.iter()) {
            w.u32(*v as u32);
        }
        let m = &self.modal;
        w.u8(u8::from(m.relative_xyz)
            | u8::from(m.relative_e) << 1
            | u8::from(m.inches) << 2
            | u8::from(m.retracted) << 3);
        for v in [m.feed_mm_s, m.feed_pct, m.flow_pct] {
            w.f32(v);
        }
        for v in m
            .offset_mm
            .iter()
            .chain([m.logical_e_mm].iter())
            .chain(m.machine_mm.iter())
        {
            w.put(&v.to_bits().to_le_bytes());
        }
        for v in [self.retract_mm, self.hotend_c, self.bed_c] {
            w.f32(v);
        }
        w.u8(self.fan_pwm);
        w.u32(size);
        let crc = super::crc::crc32(&w.buf[..JOB_RECORD_LEN - 4]);
        w.u32(crc);
        w.buf
    }

    /// Read a record, checking its framing and that its values make sense. A format-2 record
    /// of a host job loads too (see the module documentation).
    pub fn decode(bytes: &[u8]) -> Result<PausedJob, RecordError> {
        let v2 = bytes.len() >= 2 && u16::from_le_bytes([bytes[0], bytes[1]]) == 2;
        let body = if v2 {
            checked_body(bytes, 2, JOB_BODY_LEN_V2)?
        } else {
            checked_body(bytes, JOB_FORMAT_VERSION, JOB_BODY_LEN)?
        };
        let mut r = Reader { buf: body, at: 0 };
        let kind = r.u8();
        let pos = r.u32();
        let len = usize::from(r.u8());
        let raw: [u8; JOB_PATH_CAP] = r.take();
        let source = match kind {
            1 => JobSource::Host { line: pos },
            2 if v2 => return Err(RecordError::OutOfRange("job source")),
            2 => {
                let text = raw
                    .get(..len)
                    .and_then(|b| core::str::from_utf8(b).ok())
                    .ok_or(RecordError::OutOfRange("SD path"))?;
                let mut path = heapless::String::new();
                path.push_str(text)
                    .map_err(|_| RecordError::OutOfRange("SD path"))?;
                JobSource::Sd {
                    path,
                    offset: pos,
                    size: 0,
                }
            }
            _ => return Err(RecordError::OutOfRange("job source")),
        };
        let layer = r.u32();
        let boundary_z_um = r.u32() as i32;
        let mut steps = || [0; AXES].map(|_: i32| r.u32() as i32);
        let boundary_steps = steps();
        let park_steps = steps();
        let flags = r.u8();
        if flags & !0b1111 != 0 {
            return Err(RecordError::OutOfRange("modal flags"));
        }
        let feed_mm_s = r.f32();
        let feed_pct = r.f32();
        let flow_pct = r.f32();
        let mut f64s = || [0.0; AXES].map(|_: f64| f64::from_bits(u64::from_le_bytes(r.take())));
        let [ox, oy, oz, logical_e_mm] = f64s();
        let offset_mm = [ox, oy, oz];
        let machine_mm = f64s();
        let modal = ModalState {
            relative_xyz: flags & 1 != 0,
            relative_e: flags & 2 != 0,
            inches: flags & 4 != 0,
            retracted: flags & 8 != 0,
            feed_mm_s,
            feed_pct,
            flow_pct,
            offset_mm,
            logical_e_mm,
            machine_mm,
        };
        let retract_mm = r.f32();
        let hotend_c = r.f32();
        let bed_c = r.f32();
        let fan_pwm = r.u8();
        let size = if v2 { 0 } else { r.u32() };
        let source = match source {
            JobSource::Sd { path, offset, .. } if offset <= size => {
                JobSource::Sd { path, offset, size }
            }
            JobSource::Host { line } if size == 0 => JobSource::Host { line },
            _ => return Err(RecordError::OutOfRange("SD offset or size")),
        };
        let finite = [feed_mm_s, feed_pct, flow_pct, retract_mm, hotend_c, bed_c]
            .iter()
            .all(|v| v.is_finite())
            && offset_mm
                .iter()
                .chain(machine_mm.iter())
                .all(|v| v.is_finite())
            && logical_e_mm.is_finite();
        if !finite || feed_mm_s <= 0.0 || hotend_c < 0.0 || bed_c < 0.0 || retract_mm < 0.0 {
            return Err(RecordError::OutOfRange("job value"));
        }
        Ok(PausedJob {
            source,
            layer,
            boundary_z_um,
            boundary_steps,
            park_steps,
            modal,
            retract_mm,
            hotend_c,
            bed_c,
            fan_pwm,
        })
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A job parked before layer `layer` of an SD file (or a host job when `host`).
    pub(crate) fn sample(layer: u32, host: bool) -> PausedJob {
        let source = if host {
            JobSource::Host { line: 1000 + layer }
        } else {
            let mut path = heapless::String::new();
            path.push_str("prints/benchy – 0.2mm PLA.gcode").unwrap();
            JobSource::Sd {
                path,
                offset: 123_456 + layer,
                size: 2_000_000,
            }
        };
        PausedJob {
            source,
            layer,
            boundary_z_um: 200 * layer as i32 + 200,
            boundary_steps: [8000, 9000, 80 * layer as i32 + 80, -1234],
            park_steps: [18_800, 18_800, 80 * layer as i32 + 2080, -1420],
            modal: ModalState {
                relative_xyz: false,
                relative_e: true,
                inches: false,
                retracted: false,
                feed_mm_s: 45.0,
                feed_pct: 100.0,
                flow_pct: 95.0,
                offset_mm: [0.0, 0.0, -0.1],
                logical_e_mm: 1234.56789,
                machine_mm: [100.0, 112.5, 0.2 * f64::from(layer) + 0.2, -13.27],
            },
            retract_mm: 2.0,
            hotend_c: 210.0,
            bed_c: 60.0,
            fan_pwm: 255,
        }
    }

    #[test]
    fn both_sources_round_trip_and_damage_is_refused() {
        for host in [true, false] {
            let j = sample(7, host);
            let b = j.encode();
            assert_eq!(PausedJob::decode(&b), Ok(j));
            for i in 0..b.len() {
                let mut d = b;
                d[i] ^= 0x10;
                assert!(PausedJob::decode(&d).is_err(), "byte {i}");
            }
        }
    }

    #[test]
    fn a_longest_path_fits() {
        let mut j = sample(1, false);
        let mut path = heapless::String::new();
        for _ in 0..JOB_PATH_CAP {
            path.push('a').unwrap();
        }
        j.source = JobSource::Sd {
            path,
            offset: 9,
            size: 9,
        };
        assert_eq!(PausedJob::decode(&j.encode()), Ok(j));
    }

    /// `j`'s record in format 2 (format 3 without the size, version 2, its own CRC).
    fn as_format_2(j: &PausedJob) -> Vec<u8> {
        let b = j.encode();
        let mut v = b[..4 + JOB_BODY_LEN_V2].to_vec();
        v[0..2].copy_from_slice(&2u16.to_le_bytes());
        v[2..4].copy_from_slice(&(JOB_BODY_LEN_V2 as u16).to_le_bytes());
        let crc = crate::storage::crc32(&v);
        v.extend_from_slice(&crc.to_le_bytes());
        v
    }

    #[test]
    fn a_format_2_host_record_loads_and_an_sd_one_is_refused() {
        let host = sample(3, true);
        assert_eq!(PausedJob::decode(&as_format_2(&host)), Ok(host));
        assert_eq!(
            PausedJob::decode(&as_format_2(&sample(3, false))),
            Err(RecordError::OutOfRange("job source"))
        );
    }

    #[test]
    fn an_offset_past_the_file_size_is_refused() {
        let mut j = sample(2, false);
        if let JobSource::Sd { size, offset, .. } = &mut j.source {
            *size = *offset - 1;
        }
        assert_eq!(
            PausedJob::decode(&j.encode()),
            Err(RecordError::OutOfRange("SD offset or size"))
        );
    }
}
