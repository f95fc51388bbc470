//! BigTreeTech SKR 2 board support (bin-only modules of the `skr2` image).
//!
//! * [`pins`] — the whole pin map, with sources;
//! * [`drivers`] — portable `embedded-hal` drivers (steppers, endstops, pause button, idle
//!   timeout, homing) that a simulator can run with its own pins;
//! * [`clock`] — TIM5 time base (4 MHz, 64-bit);
//! * [`stepper`] — the step interrupt and its event queue;
//! * [`heaters`] — thermistor sampling, software PWM, hot-end fan;
//! * [`safety`] — heaters off from any context (panic, HardFault).

pub mod clock;
pub mod drivers;
pub mod heaters;
pub mod pins;
pub mod safety;
pub mod stepper;
