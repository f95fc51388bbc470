//! ADC1 and the heaters it measures: the heater MOSFET pins' duty drives the simulator's own
//! heater plants (`sim::heater::HeaterModel`, the Ender-3 hot end and bed), whose thermistors
//! give the voltages ADC1 converts (through the firmware's thermistor curve and the SKR 2's
//! 4.7 kΩ divider, as `HeaterModel::adc` computes them) — the loop from the image's PWM to its
//! own temperature readings is closed on the emulated board.
//!
//! ADC1 registers (RM0090 §13.13, table 71 "ADC register map"): SR 0x00 (AWD 0, EOC 1, JEOC 2,
//! JSTRT 3, STRT 4, OVR 5; §13.13.1), CR1 0x04, CR2 0x08 (ADON 0, CONT 1, ALIGN 11, SWSTART
//! 30; §13.13.3), SMPR1/SMPR2 0x0C/0x10 (3 bits per channel: 3, 15, 28, 56, 84, 112, 144, 480
//! cycles; §13.13.4-5), SQR1..3 0x2C..0x34 (SQ1 = SQR3 4:0, the channel converted first;
//! §13.13.9-11), DR 0x4C (§13.13.14; reading it clears EOC). Common registers at +0x300: CCR
//! 0x04 (ADCPRE 17:16: PCLK2 / 2, 4, 6, 8; §13.13.16). A conversion takes the sampling time
//! plus 12 ADCCLK cycles (§13.5 "Channel-wise programmable sampling time": Tconv = sampling
//! time + 12 cycles); STRT sets at SWSTART, EOC at the end. Channels: 1 = PA1 (bed thermistor
//! TB), 2 = PA2 (hot-end thermistor TH0); any other channel reads mid-scale. Not modelled:
//! scan and continuous modes, injected channels, the watchdog, DMA, ADC2/ADC3.
//!
//! Heater power needs both the MOSFET gate (PB3 hot end, PD7 bed) high and SAFE_POWER (PC13)
//! high: Klipper's SKR 2 config says PC13 "needs pulling high to pass power to stepper drivers
//! and most FETs".

use crate::time::{s_from_cyc, Cyc, CPU_HZ, PCLK2_HZ};
use sim::heater::{HeaterModel, HeaterParams};

/// Heater index: hot end.
pub const HOTEND: usize = 0;
/// Heater index: bed.
pub const BED: usize = 1;

/// Plant integration step, cycles (10 ms, well below the hot end's 1.5 s sensor lag).
const PLANT_STEP: Cyc = CPU_HZ / 100;

/// The two heaters as plants, driven by their pins.
#[derive(Clone, Debug)]
pub struct Heaters {
    /// Hot end, bed.
    pub plants: [HeaterModel; 2],
    /// Power applied now (gate high and SAFE_POWER high).
    powered: [bool; 2],
    /// Powered cycles since `last_t`.
    on_cyc: [Cyc; 2],
    last_t: Cyc,
    /// Highest temperature each reached, °C.
    pub max_c: [f32; 2],
    /// Total powered time of each, cycles.
    pub powered_total: [Cyc; 2],
    /// When each was last switched on (None: off now).
    pub on_since: [Option<Cyc>; 2],
}

impl Default for Heaters {
    fn default() -> Self {
        Heaters {
            plants: [
                HeaterModel::new(HeaterParams::ENDER3_HOTEND),
                HeaterModel::new(HeaterParams::ENDER3_BED),
            ],
            powered: [false; 2],
            on_cyc: [0; 2],
            last_t: 0,
            max_c: [25.0; 2],
            powered_total: [0; 2],
            on_since: [None; 2],
        }
    }
}

impl Heaters {
    fn accumulate(&mut self, now: Cyc) {
        let dt = now.saturating_sub(self.last_t);
        for i in 0..2 {
            if self.powered[i] {
                self.on_cyc[i] += dt;
                self.powered_total[i] += dt;
            }
        }
        self.last_t = now.max(self.last_t);
    }

    /// Heater `i` powered or not from `now` on.
    pub fn set_powered(&mut self, i: usize, on: bool, now: Cyc) {
        self.advance(now);
        self.accumulate(now);
        if self.powered[i] != on {
            self.on_since[i] = on.then_some(now);
        }
        self.powered[i] = on;
    }

    /// Is heater `i` powered now.
    pub fn powered(&self, i: usize) -> bool {
        self.powered[i]
    }

    /// Steps the plants up to `now` in [`PLANT_STEP`]s with each step's mean duty.
    pub fn advance(&mut self, now: Cyc) {
        let mut anchor = self.last_t - self.last_t % PLANT_STEP;
        while anchor + PLANT_STEP <= now {
            let end = anchor + PLANT_STEP;
            self.accumulate(end);
            for i in 0..2 {
                let duty = self.on_cyc[i] as f32 / PLANT_STEP as f32;
                self.plants[i].step(duty.clamp(0.0, 1.0), s_from_cyc(PLANT_STEP) as f32);
                self.on_cyc[i] = 0;
                self.max_c[i] = self.max_c[i].max(self.plants[i].temperature_c());
            }
            anchor = end;
        }
        self.accumulate(now);
    }
}

/// ADC1.
#[derive(Clone, Debug, Default)]
pub struct Adc {
    sr: u32,
    cr1: u32,
    cr2: u32,
    smpr: [u32; 2],
    sqr: [u32; 3],
    dr: u32,
    ccr: u32,
    /// A conversion in progress: channel and end time.
    converting: Option<(u32, Cyc)>,
    other: std::collections::BTreeMap<u32, u32>,
    /// Conversions done.
    pub conversions: u64,
}

impl Adc {
    /// Back to the reset state.
    pub fn reset(&mut self) {
        *self = Adc::default();
    }

    fn sample_cycles(&self, ch: u32) -> u64 {
        const SMP: [u64; 8] = [3, 15, 28, 56, 84, 112, 144, 480];
        let (reg, slot) = if ch >= 10 { (0, ch - 10) } else { (1, ch) };
        SMP[((self.smpr[reg] >> (3 * slot)) & 7) as usize]
    }

    /// CPU cycles of one conversion of `ch`.
    fn conv_cyc(&self, ch: u32) -> Cyc {
        let pre = 2 * (u64::from((self.ccr >> 16) & 3) + 1);
        let adc_cycles = self.sample_cycles(ch) + 12;
        adc_cycles * pre * CPU_HZ / PCLK2_HZ
    }

    /// Ends a conversion whose time is up.
    pub fn advance(&mut self, now: Cyc, heaters: &mut Heaters) {
        if let Some((ch, t)) = self.converting {
            if t <= now {
                self.converting = None;
                heaters.advance(t);
                self.dr = match ch {
                    2 => u32::from(heaters.plants[HOTEND].adc()),
                    1 => u32::from(heaters.plants[BED].adc()),
                    _ => 2048,
                };
                if self.sr & 2 != 0 {
                    self.sr |= 1 << 5; // OVR: the previous result was not read.
                }
                self.sr |= 2;
                self.conversions += 1;
            }
        }
    }

    /// When the conversion in progress ends.
    pub fn next_event(&self) -> Option<Cyc> {
        self.converting.map(|(_, t)| t)
    }

    /// Register read (`off` from 0x4001_2000).
    pub fn read(&mut self, off: u32, now: Cyc, heaters: &mut Heaters) -> u32 {
        self.advance(now, heaters);
        match off {
            0x00 => self.sr,
            0x04 => self.cr1,
            0x08 => self.cr2,
            0x0C => self.smpr[0],
            0x10 => self.smpr[1],
            0x2C..=0x34 => self.sqr[((off - 0x2C) / 4) as usize],
            0x4C => {
                self.sr &= !2;
                self.dr
            }
            0x304 => self.ccr,
            _ => self.other.get(&off).copied().unwrap_or(0),
        }
    }

    /// Register write.
    pub fn write(&mut self, off: u32, v: u32, now: Cyc, heaters: &mut Heaters) {
        self.advance(now, heaters);
        match off {
            // SR bits are rc_w0.
            0x00 => self.sr &= v,
            0x04 => self.cr1 = v,
            0x08 => {
                self.cr2 = v & !(1 << 30);
                if v & (1 << 30) != 0 && v & 1 != 0 && self.converting.is_none() {
                    let ch = self.sqr[2] & 0x1F;
                    self.sr |= 1 << 4;
                    self.converting = Some((ch, now + self.conv_cyc(ch)));
                }
            }
            0x0C => self.smpr[0] = v,
            0x10 => self.smpr[1] = v,
            0x2C..=0x34 => self.sqr[((off - 0x2C) / 4) as usize] = v,
            0x304 => self.ccr = v,
            _ => {
                self.other.insert(off, v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heater_duty_warms_the_plant_and_the_adc_sees_it() {
        let mut h = Heaters::default();
        let mut adc = Adc::default();
        adc.write(0x10, 7 << 6, 0, &mut h); // channel 2: 480 cycles
        adc.write(0x34, 2, 0, &mut h);
        adc.write(0x08, 1 | (1 << 30), 0, &mut h);
        let t = adc.next_event().unwrap();
        adc.advance(t, &mut h);
        let cold = adc.read(0x4C, t, &mut h);
        h.set_powered(HOTEND, true, t);
        let later = t + 30 * CPU_HZ;
        adc.write(0x08, 1 | (1 << 30), later, &mut h);
        adc.advance(later + 100_000, &mut h);
        let warm = adc.read(0x4C, later + 100_000, &mut h);
        // NTC on a pull-up: hotter reads lower.
        assert!(warm < cold, "{warm} < {cold}");
        assert!(h.max_c[HOTEND] > 60.0, "{}", h.max_c[HOTEND]);
    }
}
