//! The `executive` target: a little program of host bytes, time and buttons against the real
//! executive, in every policy, with heater sensor faults.

use super::{Harness, Sensor, TICK_US};
use firmware::link::{control_byte, PortId};
use firmware::motion::{PauseMode, Realtime};
use firmware::printer::{PausedLines, Policy};

/// Lines a host or a slicer file sends, so the fuzzer reaches deep states quickly.
pub const DICT: [&str; 32] = [
    "G28",
    "G1 X100 Y100 F6000",
    "G1 X10 Y200 E2 F3000",
    "G1 Z0.3 F600",
    "G1 Z5",
    "G1 X220 Y220 Z2 F12000",
    "M400",
    "M601",
    "M601 S1",
    "M602",
    "M524",
    "M25",
    "M24",
    "M108",
    "M410",
    "M109 S200",
    "M190 S60",
    "G4 P200",
    ";LAYER_CHANGE",
    ";Z:0.6",
    "G1 X50 Y50 E1.5 F1800",
    "G91",
    "G90",
    "M83",
    "G2 X60 Y60 I5 J5",
    "M761 L1",
    "M220 S300",
    "M105",
    "G92 E0",
    "M84",
    "M0",
    "M114",
];

/// The dictionary of byte 0's bit 3 (issue 31): numbers with exponents as Python and C write
/// them, lines refused for the word they name, emergency lines (read ahead of the lines
/// before them), slicer comments with exponents.
pub const DICT_31: [&str; 32] = [
    "G1 X1e-05 Y20 F3000",
    "G1 X20 E1e9",
    "G1 X1e39",
    "G1 X1.5E+02 Y2.5e1 E1e-3",
    "M104 S2e2",
    "M104 T9 S200",
    "M104 S0 T1",
    "T1",
    "M106 P9",
    "M106 S1.28e2",
    "M303 E5",
    "M569 S2 X",
    "M113 S1000000",
    "G1 X13 F0.0001",
    "G4 P1e3",
    "M112",
    "M108",
    "M410",
    "N1 M410*39",
    "N2 M112*35",
    ";Z:1e-3",
    ";LAYER_CHANGE",
    "G1 Z2e-1 F600",
    "G1 X100 Y100 E1 F6e3",
    "G1 X10 ; a*0.85",
    "M110 N0",
    "M601",
    "M602",
    "M524",
    "M400",
    "M105",
    "N3 M108*9",
];

/// The dictionary of byte 0's bit 4 (issue 31, over bit 3): a cancel followed by a host's
/// tail (cool-down, motors off, reports, moves and heat-ups of the cancelled job, numbered and
/// not), M400/M105 polling and jogs while parked.
pub const DICT_TAIL: [&str; 32] = [
    "M104 S200",
    "M140 S60",
    "M106 S255",
    "G1 X100 Y100 F6000",
    "G1 X10 Y200 E2 F3000",
    "M524",
    "M601 S1",
    "M601",
    "M602",
    "M104 S0",
    "M140 S0",
    "M104 T0 S0",
    "M106 S0",
    "M107",
    "M84",
    "M18 X Y",
    "M105",
    "M114",
    "M400",
    "M27",
    "M119",
    "M155 S1",
    "M117 cancelled",
    "G28 X",
    "G1 X0 Y220 F6000",
    "M109 S200",
    "G91",
    "G1 Z1 F600",
    "G90",
    "N1 G1 X100 Y100 F6000*72",
    "N2 M400*37",
    "M110 N0",
];

/// The policies the `executive` target runs, by the low 2 bits of its first byte: ours, the
/// conventional-firmware model `sim --policy fifo` runs (16 moves queued, the pause at the
/// tail), ours with every line while paused a manual command (`PausedLines::Manual`), ours
/// without segmentation.
pub const POLICIES: [&str; 4] = ["firmware", "fifo", "manual", "unsegmented"];

/// The policy named `POLICIES[k % 4]`.
pub fn policy_of(k: u8) -> Policy {
    match k % 4 {
        0 => Policy::FIRMWARE,
        1 => Policy::FIFO.with_queue_limit(16),
        2 => Policy {
            paused_lines: PausedLines::Manual,
            ..Policy::FIRMWARE
        },
        _ => Policy {
            segment: false,
            ..Policy::FIRMWARE
        },
    }
}

/// The `executive` target. Byte 0 chooses the policy ([`POLICIES`], low 2 bits), whether single
/// control bytes are requests on the TFT port too (bit 2; by default only on USB) and the
/// dictionary (bit 4: [`DICT_TAIL`], and then, parked at the end, an `M400` and an `M105` are
/// answered in bounded time; else bit 3: [`DICT_31`]; else [`DICT`]); the other bits are free. The rest is a little program, each byte an op (top 3 bits) and an argument
/// (low 5 bits): raw bytes to the USB (0, 1) or TFT (2) port, a dictionary line to the USB (3)
/// or TFT (4) port, time passing (5, 6), a button request (7, argument 0–23) or a sensor fault
/// (7, argument 24–31: bit 0 the bed, bits 1–2 NaN, +∞, −∞, detached; it lasts to the end).
/// Panics on a finding.
pub fn run_executive(data: &[u8]) {
    let Some((&config, data)) = data.split_first() else {
        return;
    };
    let mut h = Harness::with_policy(policy_of(config));
    let tft_controls = config & 4 != 0;
    h.p.set_control_bytes(PortId::Tft, tft_controls);
    let dict = if config & 16 != 0 {
        &DICT_TAIL
    } else if config & 8 != 0 {
        &DICT_31
    } else {
        &DICT
    };
    // Control bytes written to the TFT port (each dropped as noise unless they are requests).
    let mut tft_control_bytes = 0u32;
    let mut i = 0;
    while let Some(&b) = data.get(i) {
        i += 1;
        let (op, arg) = (b >> 5, usize::from(b & 31));
        match op {
            0..=2 => {
                let port = if op == 2 { PortId::Tft } else { PortId::Usb };
                let end = (i + arg + 1).min(data.len());
                let raw = data.get(i..end).unwrap_or(&[]).to_vec();
                i = end;
                if port == PortId::Tft {
                    let n = raw.iter().filter(|&&b| control_byte(b).is_some()).count();
                    tft_control_bytes += n as u32;
                }
                h.write(port, &raw);
            }
            3 | 4 => {
                let line = format!("{}\n", dict[arg]);
                let port = if op == 4 { PortId::Tft } else { PortId::Usb };
                h.write(port, line.as_bytes());
            }
            5 => {
                for _ in 0..=arg * 4 {
                    h.tick(TICK_US);
                }
            }
            6 => {
                for _ in 0..=arg {
                    h.tick(100 * TICK_US);
                }
            }
            _ if arg >= 24 => {
                let k = arg - 24;
                h.sensors[k & 1] = match k >> 1 {
                    0 => Sensor::Marker(f32::NAN),
                    1 => Sensor::Marker(f32::INFINITY),
                    2 => Sensor::Marker(f32::NEG_INFINITY),
                    _ => Sensor::Detached,
                };
            }
            _ => {
                let r = match arg % 6 {
                    0 => Realtime::Pause(PauseMode::Layer),
                    1 => Realtime::Pause(PauseMode::Now),
                    2 => Realtime::Resume,
                    3 => Realtime::Cancel,
                    4 => Realtime::BreakWait,
                    _ => Realtime::QuickStop,
                };
                h.request(r);
            }
        }
    }
    if config & 16 != 0 {
        h.answers_while_parked();
    }
    h.finish();
    // Control bytes on the TFT port act only where they were chosen: otherwise each one taken
    // is dropped as noise (after a halt the rest is swallowed untaken by the count).
    let ignored = h.p.port(PortId::Tft).stats().controls_ignored;
    if tft_controls {
        assert_eq!(ignored, 0);
    } else if h.p.status().state != firmware::printer::State::Halted {
        assert_eq!(ignored, tft_control_bytes, "TFT control bytes not dropped");
    } else {
        assert!(ignored <= tft_control_bytes);
    }
}
