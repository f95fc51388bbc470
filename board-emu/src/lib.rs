//! An emulated BigTreeTech SKR 2 (STM32F407VG, or the F429VG of later boards) that runs the
//! unmodified firmware image `scripts/build-firmware.sh` makes, as flashed: at 0x0800_8000
//! behind a stub for BigTreeTech's 32 KiB SD bootloader. The CPU is Unicorn's Cortex-M4
//! (QEMU's TCG); every peripheral the image touches is a model in this crate, written from
//! RM0090 (STM32F405/07/29 reference manual), the STM32F407 datasheet and PM0214 (the
//! Cortex-M4 programming manual), each register and bit cited where it is modelled. The
//! outside of the board reuses the project's own models: the TMC2209 register model of the
//! driver tests (`firmware::drivers::tmc2209::model`), the simulator's heater plants
//! (`sim::heater`) and its SD-card image builder (`sim::sd`).
//!
//! `docs/board-emu.md` says what is modelled and what is not, and how fast it runs.
#![deny(missing_docs)]

pub mod adc;
pub mod axes;
pub mod board;
pub mod cpu;
pub mod cycles;
mod exception;
pub mod fault;
pub mod flash;
pub mod gpio;
pub mod host;
pub mod iwdg;
pub mod nvic;
pub mod options;
pub mod otg;
pub mod rcc;
pub mod report;
pub mod scenario;
pub mod sdio;
pub mod serve;
pub mod setup;
pub mod time;
pub mod timer;
pub mod tmc;
pub mod usart;
pub mod usbhost;
