//! BigTreeTech SKR 2 board support (bin-only modules of the `skr2` image).
//!
//! * [`pins`] — the whole pin map, with sources;
//! * [`drivers`] — the portable `embedded-hal` drivers (steppers, endstops, pause button, idle
//!   timeout, homing), in the library as `firmware::drivers` so a simulator or a test can run
//!   them with its own pins;
//! * [`clock`] — TIM5 time base (4 MHz, 64-bit);
//! * [`flash`] — the settings store in flash sectors 10–11 (M500/M501);
//! * [`stepper`] — the step interrupt and its event queue;
//! * [`heaters`] — thermistor sampling, software PWM, hot-end fan;
//! * [`safety`] — heaters, drivers and their power off from any context (panic, HardFault,
//!   an unexpected interrupt), the fault record, and the last words on the TFT UART;
//! * [`stack`] — the MPU guard below the stack and its high-water mark;
//! * [`watchdog`] — the independent watchdog, timed from the fastest LSI;
//! * [`tmc`] — the TMC2209 UART lines;
//! * [`sd`] — the micro-SD slot on SDIO, for SD printing.

pub mod clock;
pub mod flash;
pub use firmware::drivers;
pub mod heaters;
pub mod pins;
pub mod safety;
// The micro-SD slot (SDIO) for SD printing.
pub mod sd;
pub mod stack;
pub mod stepper;
pub mod tmc;
pub mod watchdog;
