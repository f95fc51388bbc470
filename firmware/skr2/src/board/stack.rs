//! The main stack: an overflow guard and the high-water mark.
//!
//! cortex-m-rt puts the stack at the top of RAM (`_stack_start`, 0x2002_0000), growing down
//! towards the statics, which end at `_stack_end`. Unguarded, an overflow would silently
//! overwrite the statics (the `Printer`, the step queue). Here:
//!
//! * **Guard**: the MPU makes [`GUARD_BYTES`] just above the statics no-access (region 0,
//!   `AP = 000`, execute-never; PM0214 §4.2 "Memory protection unit": MPU_RBAR/MPU_RASR, the
//!   region aligned to its size; `PRIVDEFENA` keeps the default map everywhere else). The guard
//!   is larger than the largest stack frame in the image (1.3 KiB, `handle_line`; measured with
//!   `arm-none-eabi-objdump -d`, see docs/board.md), so a frame cannot jump over it. A push into
//!   it is a MemManage fault; MemManage is not enabled (SHCSR), so it escalates to HardFault,
//!   which runs at priority −1 where the MPU is off (MPU_CTRL.HFNMIENA = 0): the handler's own
//!   stacking lands in the guard's RAM, turns the heaters and drivers off, records
//!   [`crate::board::safety::Fault::StackOverflow`] (MSP inside the guard) and resets.
//! * **High-water mark**: cortex-m-rt's `paint-stack` feature fills the stack with
//!   [`PAINT`] in the reset handler; [`high_water`] scans up from the guard for the first
//!   word that is not paint any more.
//!
//! Why not flip-link (the stack below the statics, overflowing off the start of RAM): the
//! faulting push is a bus fault, and the HardFault's own stacking at the same invalid address
//! locks the core up without running any handler — the heater pins keep their level until the
//! watchdog resets the chip. The guard above keeps the handler running.

use cortex_m::peripheral::MPU;

/// Size of the no-access guard region, bytes (a power of two ≥ 32, > the largest frame).
pub const GUARD_BYTES: u32 = 2048;

/// cortex-m-rt's stack paint (`paint-stack` feature).
pub const PAINT: u32 = 0xCCCC_CCCC;

extern "C" {
    // cortex-m-rt's link.x: the end of the statics (`.uninit`) and the top of the stack.
    static _stack_end: u32;
    static _stack_start: u32;
}

/// The stack's layout: `[guard_base, guard_top)` is the guard, `[guard_top, top)` the stack.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// First byte of the guard.
    pub guard_base: u32,
    /// One past the guard: the lowest byte the stack may use.
    pub guard_top: u32,
    /// One past the stack's highest byte (the initial MSP).
    pub top: u32,
}

impl Layout {
    /// Usable stack, bytes.
    pub fn size(self) -> u32 {
        self.top.saturating_sub(self.guard_top)
    }
}

/// The layout from the linker's symbols.
pub fn layout() -> Layout {
    // Only the addresses of the linker symbols are taken, never their contents.
    let (end, top) = (
        core::ptr::addr_of!(_stack_end) as u32,
        core::ptr::addr_of!(_stack_start) as u32,
    );
    let guard_base = end.div_ceil(GUARD_BYTES) * GUARD_BYTES;
    Layout {
        guard_base,
        guard_top: guard_base + GUARD_BYTES,
        top,
    }
}

/// Arms the guard (MPU region 0). Call once, early in `main`.
pub fn guard() {
    let l = layout();
    // RASR: XN (bit 28), AP = 000 no access (bits 26:24), SIZE = log2(bytes) − 1 (bits 5:1),
    // ENABLE (bit 0). RBAR: the base (aligned to the size), VALID = 0 (region from RNR).
    let size_field = GUARD_BYTES.trailing_zeros() - 1;
    let rasr = (1 << 28) | (size_field << 1) | 1;
    // SAFETY: MPU register writes before any code relies on the MPU's state; the region covers
    // only RAM that nothing is linked into (between the statics and the stack's usable part).
    unsafe {
        let mpu = &*MPU::PTR;
        mpu.ctrl.write(0);
        mpu.rnr.write(0);
        mpu.rbar.write(l.guard_base);
        mpu.rasr.write(rasr);
        // ENABLE | PRIVDEFENA; HFNMIENA stays 0 (MPU off in HardFault).
        mpu.ctrl.write(0b101);
    }
    cortex_m::asm::dsb();
    cortex_m::asm::isb();
}

/// True if `sp` lies in the guard or below it: the stack overflowed.
pub fn overflowed(sp: u32) -> bool {
    sp < layout().guard_top
}

/// Bytes of the stack used at its deepest since reset, and the stack's size: scans up from
/// the guard for the first word that is not [`PAINT`] (under 0.3 ms for the whole stack).
pub fn high_water() -> (u32, u32) {
    let l = layout();
    let mut at = l.guard_top;
    while at < l.top {
        // SAFETY: a word-aligned read inside the stack's RAM, which is always mapped.
        let w = unsafe { core::ptr::read_volatile(at as *const u32) };
        if w != PAINT {
            break;
        }
        at += 4;
    }
    (l.top - at, l.size())
}
