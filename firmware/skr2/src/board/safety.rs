//! The last line of defence: heaters off, stepper drivers disabled and their power switched
//! off, by raw register writes that work from any context (panic, HardFault) without the HAL's
//! drivers, and a last line on the TFT UART. USB cannot be served once the executor has
//! stopped, so the fault is also recorded in RAM that survives a reset ([`record_fault`]); the
//! board then resets (at once, or by the watchdog) and the next start-up says what happened on
//! every port, USB included ([`reset_cause`]), as Marlin reports a watchdog reset.

use core::mem::MaybeUninit;
use core::ptr::{addr_of, addr_of_mut};
use embassy_stm32::pac;

/// What stopped the firmware before a reset.
// `HardFault` is the exception's name in the Arm documentation: kept.
#[allow(clippy::enum_variant_names)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// A Rust panic.
    Panic,
    /// A HardFault exception (a fault no other handler took).
    HardFault,
    /// A HardFault with the stack pointer inside the stack's guard region: the stack overflowed.
    StackOverflow,
    /// An exception or interrupt this image never enables (cortex-m-rt's `DefaultHandler`):
    /// the IRQ number as cortex-m-rt gives it (exceptions negative: SysTick −1, PendSV −2 …).
    Unexpected(i16),
}

impl Fault {
    fn code(self) -> [u32; 2] {
        match self {
            Fault::Panic => [1, 0],
            Fault::HardFault => [2, 0],
            Fault::StackOverflow => [3, 0],
            Fault::Unexpected(irqn) => [4, irqn as u16 as u32],
        }
    }

    fn from_code(kind: u32, arg: u32) -> Option<Self> {
        match kind {
            1 => Some(Fault::Panic),
            2 => Some(Fault::HardFault),
            3 => Some(Fault::StackOverflow),
            4 => Some(Fault::Unexpected(arg as u16 as i16)),
            _ => None,
        }
    }
}

const FAULT_MAGIC: u32 = 0x4C50_4654;

/// The fault record: magic, kind, argument. In `.uninit` (cortex-m-rt: not zeroed at
/// start-up), so it survives a reset; read and cleared once at start-up.
#[link_section = ".uninit.layerpause_fault"]
static mut FAULT_RECORD: MaybeUninit<[u32; 3]> = MaybeUninit::uninit();

/// Records `kind` for the next start-up (the first record wins: a panic ends in a HardFault).
pub fn record_fault(kind: Fault) {
    // SAFETY: plain volatile word accesses to a static only this module touches, from a
    // handler that never returns.
    unsafe {
        let rec = addr_of_mut!(FAULT_RECORD).cast::<[u32; 3]>();
        if core::ptr::read_volatile(rec)[0] != FAULT_MAGIC {
            let [k, a] = kind.code();
            core::ptr::write_volatile(rec, [FAULT_MAGIC, k, a]);
        }
    }
}

/// Why the last reset happened, if not a plain power-up or reset button.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetCause {
    /// A recorded firmware fault.
    Fault(Fault),
    /// The independent watchdog (RCC_CSR IWDGRSTF).
    Watchdog,
}

impl core::fmt::Display for ResetCause {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let what = match self {
            ResetCause::Watchdog => {
                return f.write_str(
                    "Watchdog Reset: a loop stopped, heaters and drivers were switched off by the reset",
                )
            }
            ResetCause::Fault(Fault::Panic) => "panic",
            ResetCause::Fault(Fault::HardFault) => "HardFault",
            ResetCause::Fault(Fault::StackOverflow) => "stack overflow",
            ResetCause::Fault(Fault::Unexpected(n)) => {
                return write!(
                    f,
                    "firmware fault (unexpected interrupt, IRQ {n}) before this reset: heaters \
                     and drivers were switched off"
                )
            }
        };
        write!(
            f,
            "firmware fault ({what}) before this reset: heaters and drivers were switched off"
        )
    }
}

/// Why the last reset happened, if it was not a plain power-up or reset button: a recorded
/// fault, or the independent watchdog (RCC_CSR IWDGRSTF). Clears both, so each start-up reports
/// its own cause once.
pub fn reset_cause() -> Option<ResetCause> {
    // SAFETY: as in `record_fault`; read before anything else writes it in this run.
    let rec = unsafe {
        let rec = addr_of!(FAULT_RECORD).cast::<[u32; 3]>();
        let v = core::ptr::read_volatile(rec);
        core::ptr::write_volatile(addr_of_mut!(FAULT_RECORD).cast::<[u32; 3]>(), [0, 0, 0]);
        v
    };
    let watchdog = pac::RCC.csr().read().wdgrstf();
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    match rec {
        [FAULT_MAGIC, kind, arg] => match Fault::from_code(kind, arg) {
            Some(f) => Some(ResetCause::Fault(f)),
            None if watchdog => Some(ResetCause::Watchdog),
            None => None,
        },
        _ if watchdog => Some(ResetCause::Watchdog),
        _ => None,
    }
}

/// After a fault: reset the MCU (heaters and drivers come up off; the next start-up reports
/// the fault on every port), unless a debugger is attached (then it stops at a breakpoint).
pub fn reset_or_break() -> ! {
    if cortex_m::peripheral::DCB::is_debugger_attached() {
        loop {
            cortex_m::asm::bkpt();
        }
    }
    cortex_m::peripheral::SCB::sys_reset()
}

/// Heater MOSFET gates low (HE0 PB3, BED PD7), by BSRR writes (atomic, any context). The
/// heater task's soft PWM drives them again at its next slot; the flash driver calls this
/// before a sector erase stalls the MCU (`board::flash`).
pub fn heaters_off() {
    pac::GPIOB.bsrr().write(|w| w.set_br(3, true));
    pac::GPIOD.bsrr().write(|w| w.set_br(7, true));
}

/// Heater MOSFET gates low (HE0 PB3, BED PD7), stepper drivers disabled (EN high: X PE3, Y PD6,
/// Z PD1, E0 PC7, E1 PD13) and SAFE_POWER (PC13) low, which cuts the supply of the drivers and
/// of most MOSFETs (Klipper's SKR 2 config). Idempotent; touches only the BSRR registers, which
/// set or clear single pins atomically (a pin not in output mode, such as the sockets' pins
/// after a reversed module was found, is not driven by it). The fans keep their PWM where they
/// still have power.
pub fn all_off() {
    heaters_off();
    pac::GPIOE.bsrr().write(|w| w.set_bs(3, true));
    pac::GPIOD.bsrr().write(|w| {
        w.set_bs(6, true);
        w.set_bs(1, true);
        w.set_bs(13, true);
    });
    pac::GPIOC.bsrr().write(|w| {
        w.set_bs(7, true);
        w.set_br(13, true);
    });
}

/// Writes `text` on USART1 (the TFT header) by polling its registers, each byte given up after
/// a bounded wait (the UART may not be running).
pub fn uart_say(text: &[u8]) {
    let u = pac::USART1;
    for &b in text {
        let mut spins = 0u32;
        while !u.sr().read().txe() {
            spins += 1;
            if spins > 100_000 {
                return;
            }
        }
        u.dr().write(|w| w.set_dr(u16::from(b)));
    }
    // Let the last byte leave the shift register (a reset follows).
    let mut spins = 0u32;
    while !u.sr().read().tc() && spins < 100_000 {
        spins += 1;
    }
}
