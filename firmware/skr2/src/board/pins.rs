//! The whole SKR 2 pin map in one place.
//!
//! Sources, for every assignment below:
//! * [M] Marlin's `Marlin/src/pins/stm32f4/pins_BTT_SKR_V2_0_common.h` (BigTreeTech SKR 2
//!   Rev A/B), read for the facts only;
//! * [K] Klipper's `config/generic-bigtreetech-skr-2.cfg` (agrees with [M] on every pin both
//!   name; docs/board.md has the table side by side);
//! * [S] BigTreeTech's published SKR 2 schematic and pin diagram (`BIGTREETECH SKR 2`
//!   repository: `Hardware/BTT SKR 2 SCH.pdf`, `BIGTREETECH SKR 2.0 PIN.pdf`).
//!
//! | function | pin | source |
//! |---|---|---|
//! | X STEP / DIR / EN | PE2 / PE1 / PE3 | [M] `X_STEP_PIN`, `X_DIR_PIN`, `X_ENABLE_PIN` |
//! | Y STEP / DIR / EN | PD5 / PD4 / PD6 | [M] `Y_*_PIN` |
//! | Z STEP / DIR / EN | PA15 / PA8 / PD1 | [M] `Z_*_PIN` |
//! | E0 STEP / DIR / EN | PD15 / PD14 / PC7 | [M] `E0_*_PIN` |
//! | X / Y / Z endstop (X-STOP, Y-STOP, Z-STOP) | PC1 / PC3 / PC0 | [M] `X_STOP_PIN`, `Y_STOP_PIN`, `Z_STOP_PIN` |
//! | hot-end heater (HE0) | PB3 | [M] `HEATER_0_PIN` |
//! | bed heater (BED) | PD7 | [M] `HEATER_BED_PIN` |
//! | part-cooling fan (FAN0) | PB7 (TIM4_CH2 PWM) | [M] `FAN_PIN` |
//! | hot-end fan (FAN1) | PB6 (TIM4_CH1 PWM) | [M] `FAN1_PIN` |
//! | hot-end thermistor (TH0) | PA2 (ADC123_IN2) | [M] `TEMP_0_PIN` |
//! | bed thermistor (TB) | PA1 (ADC123_IN1) | [M] `TEMP_BED_PIN` |
//! | pause button (filament-runout connector E0DET) | PC2 | [M] `FIL_RUNOUT_PIN` |
//! | driver/heater/fan power switch (SAFE_POWER; low until the reversed-driver check passes) | PC13 | [M] `SAFE_POWER_PIN`; [K] `[output_pin motor_power] pin: PC13 value: 1` ("needs pulling high to pass power to stepper drivers and most FETs") |
//! | E1 STEP / DIR / EN (socket not used, but powered by SAFE_POWER: checked, kept disabled) | PD11 / PD10 / PD13 | [M] `E1_STEP_PIN`, `E1_DIR_PIN`, `E1_ENABLE_PIN`; [K] `#[extruder1]` |
//! | TMC2209 UART X / Y / Z / E0 (single wire, TX = RX) | PE0 / PD3 / PD0 / PC6 | [M] `X_SERIAL_TX_PIN PE0`, `Y_SERIAL_TX_PIN PD3`, `Z_SERIAL_TX_PIN PD0`, `E0_SERIAL_TX_PIN PC6`, each `*_SERIAL_RX_PIN` = its TX pin; [K] `[tmc2209 stepper_x] uart_pin: PE0` (and `PD3`, `PD0`, `PC6`) |
//! | status LED (RGB header data pin) | PE6 | [M] `NEOPIXEL_PIN`; the SKR 2 has no user LED on a GPIO, so a plain LED on the RGB header is used |
//! | USB (Type-B port, OTG FS) | PA11 / PA12 | [S] USB D− / D+ |
//! | TFT header UART (USART1) | PA9 TX / PA10 RX | [S] TFT connector; Marlin's SKR 2 example configurations put the TFT on `SERIAL_PORT 1` |
//! | HSE crystal | 8 MHz | [S] |
//!
//! The stepper drivers are TMC2209 (or A4988/DRV8825) modules in STEP/DIR mode: EN is active
//! low, a step is a rising edge. The thermistor inputs have 4.7 kΩ pull-ups to 3.3 V ([S]),
//! which is what `firmware::thermal::thermistor` assumes.

/// HSE crystal frequency on the SKR 2, Hz.
pub const HSE_HZ: u32 = 8_000_000;

use embassy_stm32::gpio::{AnyPin, Flex, Input, Level, Output, Pull, Speed};
use embassy_stm32::peripherals as P;
use embassy_stm32::Peri;
use firmware::drivers::backward::{self, Backward};

/// The driver sockets, in the order of [`SOCKET_NAMES`].
pub const SOCKETS: usize = 5;
/// The sockets as Marlin names them in its reversed-driver report. E1 (STEP PD11, DIR PD10,
/// EN PD13: [M] `E1_STEP_PIN`, `E1_DIR_PIN`, `E1_ENABLE_PIN`) is not used by this image, but
/// SAFE_POWER feeds it too, so a module in it is checked as well.
pub const SOCKET_NAMES: [&str; SOCKETS] = ["X", "Y", "Z", "E0", "E1"];

/// The driver sockets' STEP, DIR and EN pins, not configured yet: the reversed-driver check
/// ([`check_sockets`]) needs EN as an input first.
pub struct Sockets {
    /// STEP X, Y, Z, E0, E1.
    pub step: [Peri<'static, AnyPin>; SOCKETS],
    /// DIR X, Y, Z, E0, E1.
    pub dir: [Peri<'static, AnyPin>; SOCKETS],
    /// EN X, Y, Z, E0, E1 (active low).
    pub en: [Peri<'static, AnyPin>; SOCKETS],
}

/// The stepper outputs of the four used sockets (X, Y, Z, E0): STEP, DIR, EN.
pub type StepperOutputs = (
    [Output<'static>; 4],
    [Output<'static>; 4],
    [Output<'static>; 4],
);

/// Marlin's reversed-driver check (`firmware::drivers::backward`) on every socket, with
/// SAFE_POWER: each EN an input with the pull-up, each STEP driven low, 20 ms, EN read.
/// SAFE_POWER goes high only if no socket holds a module the wrong way round. The pins go back
/// to their reset state (analog, undriven) afterwards.
pub fn check_sockets(s: &mut Sockets, safe_power: &mut Output<'static>) -> Backward {
    let mut en = s.en.each_mut().map(|p| Input::new(p.reborrow(), Pull::Up));
    let mut step = s
        .step
        .each_mut()
        .map(|p| Output::new(p.reborrow(), Level::Low, Speed::Low));
    backward::check(safe_power, &mut en, &mut step, &mut embassy_time::Delay)
}

/// Configures the sockets' pins for stepping, once the check passed: STEP and DIR low, every
/// driver disabled (EN high). E1's pins are set the same way and kept for the program's life
/// (an unused module stays disabled); the four used sockets' outputs are returned.
pub fn stepper_outputs(s: Sockets) -> StepperOutputs {
    let out = |pin: Peri<'static, AnyPin>, level| Output::new(pin, level, Speed::VeryHigh);
    let [sx, sy, sz, se, s1] = s.step;
    let [dx, dy, dz, de, d1] = s.dir;
    let [ex, ey, ez, ee, e1] = s.en;
    // embassy resets a dropped output to analog: E1's stay configured for good.
    core::mem::forget([
        out(s1, Level::Low),
        out(d1, Level::Low),
        out(e1, Level::High),
    ]);
    (
        [sx, sy, sz, se].map(|p| out(p, Level::Low)),
        [dx, dy, dz, de].map(|p| out(p, Level::Low)),
        [ex, ey, ez, ee].map(|p| out(p, Level::High)),
    )
}

/// The configured GPIO pins (see the table above).
pub struct Pins {
    /// The driver sockets (configured after the reversed-driver check).
    pub sockets: Sockets,
    /// Endstop inputs X, Y, Z (pulled up).
    pub endstops: [Input<'static>; 3],
    /// Hot-end heater MOSFET gate.
    pub heater_hotend: Output<'static>,
    /// Bed heater MOSFET gate.
    pub heater_bed: Output<'static>,
    /// Pause button input (pulled up; pressed = low).
    pub pause_button: Input<'static>,
    /// Power switch of drivers, heaters and fans (high = on); low until the reversed-driver
    /// check passes.
    pub safe_power: Output<'static>,
    /// Status LED.
    pub status_led: Output<'static>,
    /// TMC2209 single-wire UART lines X, Y, Z, E0 (direction switched by `board::tmc`).
    pub tmc_uart: [Flex<'static>; 4],
}

/// The peripherals the board uses besides plain GPIO.
pub struct Periph {
    /// USB OTG FS and its D+ (PA12) / D− (PA11) pins.
    pub usb: (
        Peri<'static, P::USB_OTG_FS>,
        Peri<'static, P::PA12>,
        Peri<'static, P::PA11>,
    ),
    /// TFT header UART: USART1 with RX (PA10) and TX (PA9).
    pub uart: (
        Peri<'static, P::USART1>,
        Peri<'static, P::PA10>,
        Peri<'static, P::PA9>,
    ),
    /// ADC1 and the thermistor inputs TH0 (PA2) and TB (PA1).
    pub adc: (
        Peri<'static, P::ADC1>,
        Peri<'static, P::PA2>,
        Peri<'static, P::PA1>,
    ),
    /// The step timer.
    pub step_timer: Peri<'static, P::TIM5>,
    /// The independent watchdog.
    pub watchdog: Peri<'static, P::IWDG>,
    /// Fan PWM: TIM4 with FAN1 (hot-end fan, PB6 = TIM4_CH1) and FAN0 (part fan, PB7 =
    /// TIM4_CH2).
    pub fans: (
        Peri<'static, P::TIM4>,
        Peri<'static, P::PB6>,
        Peri<'static, P::PB7>,
    ),
}

/// Splits the HAL's peripherals into the configured pins and the remaining peripherals.
/// Heaters and fans start off, SAFE_POWER low; the driver sockets are not configured yet.
pub fn split(p: embassy_stm32::Peripherals) -> (Pins, Periph) {
    let pins = Pins {
        sockets: Sockets {
            step: [
                p.PE2.into(),
                p.PD5.into(),
                p.PA15.into(),
                p.PD15.into(),
                p.PD11.into(),
            ],
            dir: [
                p.PE1.into(),
                p.PD4.into(),
                p.PA8.into(),
                p.PD14.into(),
                p.PD10.into(),
            ],
            en: [
                p.PE3.into(),
                p.PD6.into(),
                p.PD1.into(),
                p.PC7.into(),
                p.PD13.into(),
            ],
        },
        endstops: [
            Input::new(p.PC1, Pull::Up),
            Input::new(p.PC3, Pull::Up),
            Input::new(p.PC0, Pull::Up),
        ],
        heater_hotend: Output::new(p.PB3, Level::Low, Speed::Low),
        heater_bed: Output::new(p.PD7, Level::Low, Speed::Low),
        pause_button: Input::new(p.PC2, Pull::Up),
        safe_power: Output::new(p.PC13, Level::Low, Speed::Low),
        status_led: Output::new(p.PE6, Level::Low, Speed::Low),
        tmc_uart: [
            Flex::new(p.PE0),
            Flex::new(p.PD3),
            Flex::new(p.PD0),
            Flex::new(p.PC6),
        ],
    };
    let periph = Periph {
        usb: (p.USB_OTG_FS, p.PA12, p.PA11),
        uart: (p.USART1, p.PA10, p.PA9),
        adc: (p.ADC1, p.PA2, p.PA1),
        step_timer: p.TIM5,
        watchdog: p.IWDG,
        fans: (p.TIM4, p.PB6, p.PB7),
    };
    (pins, periph)
}
