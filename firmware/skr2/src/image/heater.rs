//! The heater task (every 1 ms): the thermistors sampled on ADC1 and sent to the executive's
//! thermal control ([`TEMPS`]), 10 Hz software PWM of the heaters and the fans as
//! the executive last said ([`HEAT`]); and the executive's side of that exchange
//! ([`serve_heaters`], run by the motion task).

use embassy_stm32::adc::{Adc, SampleTime};
use embassy_stm32::peripherals;
use embassy_time::{Duration, Ticker};
use firmware::printer::{Printer, State};
use firmware::thermal::HeaterId;

use super::channels::{HeatOut, Temps, HEAT, TEMPS};
use super::{beat, printer_now_us, LOOP_HEATERS};
use crate::board::drivers::adc::{AdcChannels, Oversampler};
use crate::board::heaters::{self, Fans, SoftPwm, PWM_SLOTS};

/// The two thermistor inputs on ADC1 (channel 0: hotend TH0 on PA2, 1: bed TB on PA1),
/// behind the portable polled-ADC seam. embassy-stm32's F4 ADC converts synchronously
/// (≈ 23 µs at 480 cycles), so a read is always ready.
struct ThermistorAdc {
    adc: Adc<'static, peripherals::ADC1>,
    hotend: embassy_stm32::Peri<'static, peripherals::PA2>,
    bed: embassy_stm32::Peri<'static, peripherals::PA1>,
}

impl AdcChannels for ThermistorAdc {
    type Error = core::convert::Infallible;
    fn read(&mut self, channel: u8) -> nb::Result<u16, Self::Error> {
        Ok(match channel {
            0 => self
                .adc
                .blocking_read(&mut self.hotend, SampleTime::CYCLES480),
            _ => self.adc.blocking_read(&mut self.bed, SampleTime::CYCLES480),
        })
    }
}

/// The heaters go off when the executive has said nothing for this long, µs (it answers every
/// reading within a motion tick; a stalled executive is the watchdog's, this only makes sure
/// no heater stays on meanwhile on an old duty).
const HEAT_STALE_US: u64 = 300_000;

/// The executive's side (motion task, every tick): the latest temperatures into the thermal
/// control, its duties and fans back to the heater task.
pub(super) fn serve_heaters(p: &mut Printer) {
    let Some(t) = TEMPS.try_take() else { return };
    let hotend_duty = p.thermal_sample(HeaterId::Hotend, t.hotend_c, t.t_us);
    let bed_duty = p.thermal_sample(HeaterId::Bed, t.bed_c, t.t_us);
    HEAT.signal(HeatOut {
        hotend_duty,
        bed_duty,
        hotend_fan_on: p.thermal().hotend_fan_on(),
        part_fan_pwm: p.fan_pwm(),
        halted: p.state() == State::Halted,
    });
}

#[embassy_executor::task]
pub(super) async fn heater_task(
    adc: (
        embassy_stm32::Peri<'static, peripherals::ADC1>,
        embassy_stm32::Peri<'static, peripherals::PA2>,
        embassy_stm32::Peri<'static, peripherals::PA1>,
    ),
    mut hotend: SoftPwm,
    mut bed: SoftPwm,
    mut fans: Fans,
) {
    let (adc1, th0, tb) = adc;
    let mut adc = ThermistorAdc {
        adc: Adc::new(adc1),
        hotend: th0,
        bed: tb,
    };
    let mut sampler: Oversampler<2> = Oversampler::new();
    let tables = heaters::tables();
    let mut ticker = Ticker::every(Duration::from_millis(1));
    let mut slot: u32 = 0;
    let mut heard_us: u64 = 0;
    loop {
        ticker.next().await;
        beat(LOOP_HEATERS);
        // One conversion per tick, channels in turn: a reading of each every 32 ms, the
        // average of 16 conversions (the converter is synchronous: never WouldBlock here).
        let _ = sampler.poll(&mut adc);
        if slot == 0 {
            let (Some(raw_h), Some(raw_b)) = (sampler.latest(0), sampler.latest(1)) else {
                hotend.tick(slot);
                bed.tick(slot);
                slot = (slot + 1) % PWM_SLOTS;
                continue;
            };
            // Faults travel as ±∞ markers the thermal control understands.
            TEMPS.signal(Temps {
                hotend_c: tables[0].celsius_marked(raw_h),
                bed_c: tables[1].celsius_marked(raw_b),
                t_us: printer_now_us(),
            });
        }
        let now = printer_now_us();
        if let Some(out) = HEAT.try_take() {
            heard_us = now;
            if out.halted {
                hotend.off();
                bed.off();
            } else {
                hotend.set_duty(out.hotend_duty);
                bed.set_duty(out.bed_duty);
            }
            fans.set_hotend(out.hotend_fan_on);
            fans.set_part(out.part_fan_pwm);
        } else if now.saturating_sub(heard_us) >= HEAT_STALE_US {
            // Nothing said yet, or nothing for too long: heaters off (the fans as they were).
            hotend.off();
            bed.off();
        }
        hotend.tick(slot);
        bed.tick(slot);
        slot = (slot + 1) % PWM_SLOTS;
    }
}
