//! The heater task (every 1 ms): the thermistors sampled on ADC1 and fed to the executive's
//! thermal control, 10 Hz software PWM of the heaters, and the fans.

use embassy_stm32::adc::{Adc, SampleTime};
use embassy_stm32::peripherals;
use embassy_time::{Duration, Ticker};
use firmware::printer::State;
use firmware::thermal::HeaterId;

use super::{beat, printer_now_us, Shared, LOOP_HEATERS};
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

#[embassy_executor::task]
pub(super) async fn heater_task(
    printer: Shared,
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
            let c_h = tables[0].celsius_marked(raw_h);
            let c_b = tables[1].celsius_marked(raw_b);
            let now = printer_now_us();
            let mut p = printer.borrow_mut();
            let d_h = p.thermal_sample(HeaterId::Hotend, c_h, now);
            let d_b = p.thermal_sample(HeaterId::Bed, c_b, now);
            if p.state() == State::Halted {
                hotend.off();
                bed.off();
            } else {
                hotend.set_duty(d_h);
                bed.set_duty(d_b);
            }
            fans.set_hotend(p.thermal().hotend_fan_on());
            fans.set_part(p.fan_pwm());
        }
        hotend.tick(slot);
        bed.tick(slot);
        slot = (slot + 1) % PWM_SLOTS;
    }
}
