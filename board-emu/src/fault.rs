//! Faults injected from the emulator's side: the image is never modified. Each says how it is
//! done.

use crate::board::Stall;
use crate::cpu::Emulator;
use crate::nvic::{exc, irq};
use crate::time::{cyc_from_ms, s_from_cyc, Cyc};

/// A fault to inject while a job runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Fault {
    /// Thread mode (the executor: motion, heater, host tasks) is held for 5 s while the head
    /// moves, as if the motion task were stuck in a loop; interrupts still run. Injected as
    /// a stall that starts at the executor's first read of the TIM5 counter after the
    /// injection time. The watchdog should reset the board.
    MotionStall,
    /// Thread mode held for 5 ms while the head moves (a blocking SD read, a flash program,
    /// a long USB transfer): the step interrupt runs its queue dry, then the motion loop
    /// catches up. No step may come faster than the axis's limit afterwards.
    ExecutorStall,
    /// A HardFault: debugger-style, the return address in the step interrupt's exception
    /// frame (on the stack) is overwritten with an address where nothing is mapped, so the
    /// exception return faults.
    HardFault,
    /// An interrupt nobody expects: SysTick armed and its interrupt enabled (STK_CTRL =
    /// ENABLE | TICKINT | CLKSOURCE, 1 ms), as a bootloader could leave it, while the image
    /// runs. The image has no SysTick handler: cortex-m-rt's `DefaultHandler`.
    UnexpectedIrq,
}

impl Fault {
    /// How long the injected stall lasts (stall faults).
    pub fn stall(self) -> Option<Cyc> {
        match self {
            Fault::MotionStall => Some(cyc_from_ms(5_000)),
            Fault::ExecutorStall => Some(cyc_from_ms(5)),
            _ => None,
        }
    }
}

/// The address written over the return address for [`Fault::HardFault`]: nothing is mapped
/// there (RM0090 table 1: reserved).
pub const BAD_RETURN: u32 = 0x3000_0000;

/// Injects `f` now, as its documentation says; false when its moment has not come yet (a
/// HardFault waits until the step interrupt is the active handler).
pub fn inject(emu: &mut Emulator, f: Fault) -> bool {
    let now = emu.now();
    let b = emu.board_mut();
    match f {
        Fault::MotionStall | Fault::ExecutorStall => {
            b.stall = f.stall().map(|duration| Stall {
                after: now,
                duration,
            });
            true
        }
        Fault::UnexpectedIrq => {
            b.nvic.systick.load = 167_999;
            b.nvic.systick.write_ctrl(now, 0b111);
            b.notes.push(format!(
                "SysTick armed (1 ms, TICKINT) at t = {:.4} s",
                s_from_cyc(now)
            ));
            true
        }
        Fault::HardFault => {
            if b.nvic.stack.last() != Some(&(exc::IRQ0 + irq::TIM5)) {
                return false;
            }
            // The stacked return address: word 6 of the frame the entry pushed.
            let Some(slot) = b.frame_sp.last().map(|sp| sp + 24) else {
                return false;
            };
            let old = emu.peek32(slot);
            emu.poke32(slot, BAD_RETURN);
            emu.board_mut().notes.push(format!(
                "HardFault injected: TIM5 frame's return address {old:#010x} -> {BAD_RETURN:#010x} at t = {:.4} s",
                s_from_cyc(now)
            ));
            true
        }
    }
}
