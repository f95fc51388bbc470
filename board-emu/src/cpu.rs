//! The Cortex-M4 core: Unicorn (QEMU's TCG) executes Thumb-2 and VFP instructions; this module
//! maps the STM32F407's memory (RM0090 §2.3, table 1 and §2.4 "Embedded SRAM"), runs the
//! core in slices that end exactly at the next peripheral event, sleeps through WFI/WFE by
//! fast-forwarding virtual time, and does what Unicorn does not: exception entry and return.
//!
//! Exception entry (ARMv7-M ARM B1.5.6 "Exception entry behavior", PushStack): the 8-word
//! frame (R0-R3, R12, LR, return address, xPSR) — 26 words with S0-S15 and FPSCR when
//! CONTROL.FPCA says the thread used the FPU (the extended frame; what lazy stacking defers is
//! stored at once here, which software cannot tell apart) — on the stack in use, aligned to 8
//! bytes (CCR.STKALIGN; xPSR bit 9 records the padding), LR = EXC_RETURN (0xFFFFFFF1/F9/FD,
//! bit 4 clear for an extended frame), CONTROL.FPCA and SPSEL cleared, the handler's address
//! from the vector table at VTOR. Exception return (B1.5.8): a branch to an EXC_RETURN value
//! lands on a trap page at 0xFFFF_F000 and the frame is popped from the stack it names.
//! Unicorn itself is kept in Thread mode (IPSR = 0) throughout, so that its own M-profile
//! exception logic, which has no NVIC in Unicorn, is never used; the exception number is kept
//! here (`Nvic::stack`), and `mrs IPSR` in a handler reads 0 (the image does not read it).
//!
//! Faults: an access to unmapped memory or an undefined instruction escalates to HardFault
//! (as with MemManage/BusFault/UsageFault disabled, the reset state, B1.5.1); a fault in the
//! HardFault handler is a lockup, which ends the run.

use crate::board::{Board, Stop};
use crate::cycles::Acr;
use crate::flash::{STORE_BASE, STORE_LEN};
use crate::rcc::ResetKind;
use crate::time::{Cyc, CPU_HZ};
use anyhow::{anyhow, Result};
use unicorn_engine::{
    uc_error, Arch, ArmCpuModel, HookType, MemType, Mode, Prot, RegisterARM, Unicorn,
};

/// Longest slice of busy cycles between two looks at the peripherals (about 60 µs).
const MAX_SLICE: u64 = 10_000;
/// How long an interrupt masked by a critical section is watched block by block, so that it
/// is taken as soon as it is unmasked (100 µs; see `run_until`).
const MASKED_FINE: Cyc = 16_800;
/// The bootloader stub's entry (its vector table is at 0x0800_0000).
const STUB_ENTRY: u32 = 0x0800_0008;
/// Where the image starts (what the SKR 2's SD bootloader jumps to).
pub const IMAGE_BASE: u32 = 0x0800_8000;
/// Trap page for EXC_RETURN branches.
const TRAP_PAGE: u64 = 0xFFFF_F000;

/// What a run of the core ended with.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RunEnd {
    /// The time limit was reached.
    Time,
    /// The core locked up (a fault in the HardFault handler).
    Lockup(String),
    /// A caller's condition became true.
    Condition,
}

/// Which image and how the board was started.
pub struct Emulator<'a> {
    /// The engine with the board as its data.
    pub uc: Unicorn<'a, Board>,
    /// The image (as flashed at 0x0800_8000).
    pub image: Vec<u8>,
    /// Faults taken (HardFault entries), with time and cause.
    pub faults: Vec<(Cyc, String)>,
    /// Where slices start, counted (`BOARD_EMU_PROFILE=1`: a coarse profile for debugging).
    pub profile: Option<std::collections::BTreeMap<u32, u64>>,
}

/// The bootloader stub: a vector table (initial SP, reset vector) and five instructions that
/// do what BigTreeTech's SD bootloader does when it has nothing to flash: load the image's
/// initial stack pointer from 0x0800_8000 into MSP and jump to its reset vector (VTOR is left
/// as it is: the image's reset handler sets it).
fn stub() -> Vec<u8> {
    let mut s = Vec::new();
    s.extend_from_slice(&0x2002_0000u32.to_le_bytes());
    s.extend_from_slice(&(STUB_ENTRY | 1).to_le_bytes());
    for h in [
        0x4803u16, // ldr r0, [pc, #12]   ; r0 = 0x08008000
        0x6801,    // ldr r1, [r0]        ; the image's initial SP
        0xF381, 0x8808, // msr MSP, r1
        0x6841, // ldr r1, [r0, #4]    ; its reset vector
        0x4708, // bx r1
        0xBF00, 0xBF00, // nops: the literal goes on a word boundary
    ] {
        s.extend_from_slice(&h.to_le_bytes());
    }
    s.extend_from_slice(&IMAGE_BASE.to_le_bytes());
    s
}

/// Marks WFI/WFE/SEV instructions (16-bit BF30/BF20/BF40, 32-bit F3AF 8003/8002/8004) in
/// the image by halfword: 1 WFI, 2 WFE, 3 SEV.
fn scan_special(image: &[u8]) -> Vec<u8> {
    let base_hw = ((IMAGE_BASE - 0x0800_0000) / 2) as usize;
    let mut special = vec![0u8; base_hw + image.len() / 2 + 2];
    let hw = |i: usize| u16::from_le_bytes([image[2 * i], image[2 * i + 1]]);
    for i in 0..image.len() / 2 {
        let k = match hw(i) {
            0xBF30 => 1,
            0xBF20 => 2,
            0xBF40 => 3,
            0xF3AF if 2 * i + 3 < image.len() => match hw(i + 1) {
                0x8003 => 1,
                0x8002 => 2,
                0x8004 => 3,
                _ => 0,
            },
            _ => 0,
        };
        special[base_hw + i] = k;
    }
    special
}

pub(crate) fn uc_err(e: uc_error) -> anyhow::Error {
    anyhow!("unicorn: {e:?}")
}

impl<'a> Emulator<'a> {
    /// Maps memory, loads the stub and `image`, installs the hooks; the board is powered on.
    pub fn new(mut board: Board, image: Vec<u8>, chip_f429: bool) -> Result<Self> {
        board.special = scan_special(&image);
        let mut uc = Unicorn::new_with_data(Arch::ARM, Mode::THUMB | Mode::MCLASS, board)
            .map_err(|e| anyhow!("step 1: {e:?}"))?;
        uc.ctl_set_cpu_model(ArmCpuModel::CORTEX_M4 as i32)
            .map_err(|e| anyhow!("step 2: {e:?}"))?;
        // Code flash: sectors 0-9 (the stub and the image).
        uc.mem_map(0x0800_0000, 0xC_0000, Prot::READ | Prot::EXEC)
            .map_err(|e| anyhow!("step 3: {e:?}"))?;
        uc.mem_write(0x0800_0000, &stub())
            .map_err(|e| anyhow!("step 4: {e:?}"))?;
        if image.len() > (STORE_BASE - IMAGE_BASE) as usize {
            return Err(anyhow!(
                "image of {} bytes overlaps the settings sectors",
                image.len()
            ));
        }
        uc.mem_write(u64::from(IMAGE_BASE), &image)
            .map_err(|e| anyhow!("step 5: {e:?}"))?;
        // Settings sectors 10-11: through the flash interface model.
        uc.mmio_map(
            u64::from(STORE_BASE),
            STORE_LEN as u64,
            Some(|uc: &mut Unicorn<Board>, off: u64, size: usize| {
                uc.get_data_mut().store_read(off, size)
            }),
            Some(|uc: &mut Unicorn<Board>, off: u64, size: usize, v: u64| {
                uc.get_data_mut().store_write(off, size, v)
            }),
        )
        .map_err(|e| anyhow!("step 6: {e:?}"))?;
        // System memory, OTP and the device ID: flash size 1024 KiB at 0x1FFF_7A22 (RM0090
        // §39.2 "Flash size"), a unique ID at 0x1FFF_7A10 (§39.1).
        uc.mem_map(0x1FFF_0000, 0x8000, Prot::READ)
            .map_err(|e| anyhow!("step 7: {e:?}"))?;
        uc.mem_write(
            0x1FFF_7A10,
            &[0x45, 0x4D, 0x55, 0x00, 0x53, 0x4B, 0x52, 0x32, 1, 2, 3, 4],
        )
        .map_err(|e| anyhow!("step 8: {e:?}"))?;
        uc.mem_write(0x1FFF_7A22, &1024u16.to_le_bytes())
            .map_err(|e| anyhow!("step 9: {e:?}"))?;
        uc.mem_map(0x1FFF_C000, 0x1000, Prot::READ)
            .map_err(|e| anyhow!("step 10: {e:?}"))?;
        // CCM (64 KiB) and SRAM (128 KiB; the F429 has 64 KiB more at 0x2002_0000).
        uc.mem_map(0x1000_0000, 0x1_0000, Prot::ALL)
            .map_err(|e| anyhow!("step 11: {e:?}"))?;
        let sram = if chip_f429 { 0x3_0000 } else { 0x2_0000 };
        uc.mem_map(0x2000_0000, sram, Prot::READ | Prot::WRITE | Prot::EXEC)
            .map_err(|e| anyhow!("step 12: {e:?}"))?;
        // Peripherals: APB1, APB2, AHB1 (0x4000_0000-0x4007_FFFF), AHB2 (USB OTG FS), the
        // Cortex-M4's private peripheral bus.
        for (base, len) in [
            (0x4000_0000u64, 0x8_0000u64),
            (0x5000_0000, 0x4_0000),
            (0x5006_0000, 0x1000),
            (0xE000_0000, 0x10_0000),
        ] {
            uc.mmio_map(
                base,
                len,
                Some(move |uc: &mut Unicorn<Board>, off: u64, size: usize| {
                    let in_thread = uc.get_data().nvic.stack.is_empty();
                    uc.get_data_mut()
                        .mmio_read((base + off) as u32, size, in_thread)
                }),
                Some(
                    move |uc: &mut Unicorn<Board>, off: u64, size: usize, v: u64| {
                        // The write asks for a stop before the next instruction (stop_at): the
                        // code hook stops there. Stopping inside the access would restart it.
                        uc.get_data_mut().mmio_write((base + off) as u32, size, v);
                    },
                ),
            )
            .map_err(|e| anyhow!("step 13: {e:?}"))?;
        }
        uc.mem_map(TRAP_PAGE, 0x1000, Prot::READ | Prot::EXEC)
            .map_err(|e| anyhow!("step 14: {e:?}"))?;
        // Every translation block: its instructions and cycles (`crate::cycles`; the cost of
        // its code worked out once per block address), charged before it runs; stop before
        // it when the slice is over. A block hook is called before the block's own exit
        // check, so a stop here keeps the block from running; a block that starts before the
        // slice's end runs whole (a slice may end a few cycles late).
        uc.add_block_hook(
            1,
            0,
            move |uc: &mut Unicorn<Board>, addr: u64, size: u32| {
                let a = addr as u32;
                let b = uc.get_data_mut();
                if b.cycles >= b.stop_at {
                    let _ = uc.emu_stop();
                    return;
                }
                let acr = Acr::from_reg(b.flash.acr());
                let t = b.cycles;
                let (n, c) = match b.clock.run_block(a, size, t, acr) {
                    Some(r) => r,
                    None => {
                        let code = uc.mem_read_as_vec(addr, size as usize).unwrap_or_default();
                        let b = uc.get_data_mut();
                        b.clock.learn(a, crate::cycles::cost(a, &code));
                        b.clock
                            .run_block(a, size, t, acr)
                            .unwrap_or((u64::from(size / 2).max(1), Cyc::from(size / 2).max(1)))
                    }
                };
                let b = uc.get_data_mut();
                b.insns += n;
                b.cycles += c;
                let e = b.nvic.stack.last().map_or(0, |&e| usize::from(e));
                if let Some(x) = b.busy_by_exc.get_mut(e) {
                    *x += c;
                }
            },
        )
        .map_err(uc_err)?;
        // WFI/WFE/SEV, each at its address: sleep, or set the event register.
        let special: Vec<(u64, u8)> = uc
            .get_data()
            .special
            .iter()
            .enumerate()
            .filter(|(_, k)| **k != 0)
            .map(|(i, k)| (0x0800_0000 + 2 * i as u64, *k))
            .collect();
        for (a, kind) in special {
            uc.add_code_hook(
                a,
                a,
                move |uc: &mut Unicorn<Board>, addr: u64, size: u32| {
                    let b = uc.get_data_mut();
                    if kind == 3 {
                        b.event_reg = true;
                        return;
                    }
                    // QEMU's WFE raises an exception (YIELD) Unicorn treats as invalid, and its
                    // WFI halts: neither is executed, only stepped over after the sleep.
                    b.stop = Some(Stop::Sleep {
                        wfe: kind == 2,
                        next: addr as u32 + size,
                    });
                    let _ = uc.emu_stop();
                },
            )
            .map_err(uc_err)?;
        }
        uc.add_code_hook(
            TRAP_PAGE,
            TRAP_PAGE + 0xFFF,
            |uc: &mut Unicorn<Board>, addr: u64, _size: u32| {
                uc.get_data_mut().stop = Some(Stop::ExcReturn(addr as u32 | 1));
                let _ = uc.emu_stop();
            },
        )
        .map_err(uc_err)?;
        // Exceptions the core model raises itself: a branch to an EXC_RETURN value (the
        // default memory map makes 0xE000_0000 and up execute-never, so the fetch faults
        // there: that is the return), or a real fault (undefined instruction, ...).
        uc.add_intr_hook(|uc: &mut Unicorn<Board>, intno: u32| {
            let pc = uc.reg_read(RegisterARM::PC).unwrap_or(0) as u32;
            let b = uc.get_data_mut();
            b.stop = Some(if pc >= 0xFFFF_FF00 {
                Stop::ExcReturn(pc | 1)
            } else {
                Stop::CoreException { intno, pc }
            });
            let _ = uc.emu_stop();
        })
        .map_err(uc_err)?;
        // Writes to the code sectors are refused by the flash interface (no PG, or WRPERR):
        // noted, not performed.
        uc.add_mem_hook(
            HookType::MEM_WRITE_PROT,
            0x0800_0000,
            0x080B_FFFF,
            |uc: &mut Unicorn<Board>, _t: MemType, addr: u64, size: usize, _v: i64| {
                let now = uc.get_data().now();
                let b = uc.get_data_mut();
                b.flash.program(addr as u32, size, 0, now);
                b.notes
                    .push(format!("write to code flash at {addr:#010x} refused"));
                true
            },
        )
        .map_err(|e| anyhow!("step 16: {e:?}"))?;
        let mut emu = Emulator {
            uc,
            image,
            faults: Vec::new(),
            profile: std::env::var_os("BOARD_EMU_PROFILE").map(|_| Default::default()),
        };
        emu.power_on(ResetKind::PowerOn)?;
        Ok(emu)
    }

    /// The board.
    pub fn board(&self) -> &Board {
        self.uc.get_data()
    }

    /// The board, mutably.
    pub fn board_mut(&mut self) -> &mut Board {
        self.uc.get_data_mut()
    }

    /// Virtual time now.
    pub fn now(&self) -> Cyc {
        self.board().now()
    }

    pub(crate) fn reg(&self, r: RegisterARM) -> u32 {
        self.uc.reg_read(r).unwrap_or(0) as u32
    }

    pub(crate) fn set_reg(&mut self, r: RegisterARM, v: u32) {
        let _ = self.uc.reg_write(r, u64::from(v));
    }

    pub(crate) fn read32(&self, a: u32) -> u32 {
        let mut b = [0u8; 4];
        match self.uc.mem_read(u64::from(a), &mut b) {
            Ok(()) => u32::from_le_bytes(b),
            Err(_) => 0,
        }
    }

    pub(crate) fn write32(&mut self, a: u32, v: u32) -> bool {
        self.uc.mem_write(u64::from(a), &v.to_le_bytes()).is_ok()
    }

    /// Resets the core and the peripherals (RAM and flash keep their contents) and starts
    /// the bootloader stub.
    pub fn power_on(&mut self, kind: ResetKind) -> Result<()> {
        if kind != ResetKind::PowerOn || !self.board().resets.is_empty() {
            self.board_mut().reset(kind);
        } else {
            self.board_mut().rcc.reset(kind);
            self.board_mut().resets.push((0, kind));
        }
        for r in [
            RegisterARM::PRIMASK,
            RegisterARM::BASEPRI,
            RegisterARM::FAULTMASK,
            RegisterARM::CONTROL,
        ] {
            self.set_reg(r, 0);
        }
        let sp = self.read32(0x0800_0000);
        self.set_reg(RegisterARM::MSP, sp);
        self.set_reg(RegisterARM::SP, sp);
        self.set_reg(RegisterARM::LR, 0xFFFF_FFFF);
        self.set_reg(RegisterARM::XPSR, 1 << 24);
        self.uc
            .reg_write(RegisterARM::PC, u64::from(STUB_ENTRY | 1))
            .map_err(uc_err)?;
        Ok(())
    }

    /// Paints RAM from `from` to `to` with `pattern` (the stack's high-water mark).
    pub fn paint(&mut self, from: u32, to: u32, pattern: u32) -> Result<()> {
        let n = (to.saturating_sub(from) / 4) as usize;
        let bytes: Vec<u8> = std::iter::repeat_n(pattern.to_le_bytes(), n)
            .flatten()
            .collect();
        self.uc.mem_write(u64::from(from), &bytes).map_err(uc_err)
    }

    /// The lowest address in `from..to` whose word is none of `patterns` (the deepest the
    /// stack reached).
    pub fn lowest_touched(&self, from: u32, to: u32, patterns: &[u32]) -> Option<u32> {
        let len = to.saturating_sub(from) as usize;
        let mem = self.uc.mem_read_as_vec(u64::from(from), len).ok()?;
        mem.chunks_exact(4)
            .position(|w| !patterns.contains(&u32::from_le_bytes([w[0], w[1], w[2], w[3]])))
            .map(|i| from + 4 * i as u32)
    }

    pub(crate) fn vector(&self, e: u16) -> u32 {
        let vtor = match self.board().nvic.vtor {
            0 => 0x0800_0000,
            v => v,
        };
        self.read32(vtor + 4 * u32::from(e))
    }

    /// Runs until virtual time `until` or until `stop_when` says so (checked between
    /// slices). Returns what ended the run.
    pub fn run_until(
        &mut self,
        until: Cyc,
        mut stop_when: impl FnMut(&mut Emulator<'a>) -> bool,
    ) -> Result<RunEnd> {
        let mut sleeping = false;
        let mut masked_since: Option<Cyc> = None;
        loop {
            if let Some(kind) = self.board_mut().reset_request.take() {
                self.power_on(kind)?;
                sleeping = false;
            }
            let now = self.now();
            self.board_mut().advance(now);
            // SDIO data reaches memory through DMA between instructions.
            self.board_mut().sdio.advance_with(now, true);
            for (addr, data) in self.board_mut().sdio.take_dma_writes() {
                if self.uc.mem_write(u64::from(addr), &data).is_err() {
                    self.board_mut()
                        .notes
                        .push(format!("DMA2 stream 3 write to {addr:#010x} failed"));
                }
            }
            self.board_mut().sync_irqs();
            if self.board().reset_request.is_some() {
                continue;
            }
            if stop_when(self) {
                return Ok(RunEnd::Condition);
            }
            if now >= until {
                return Ok(RunEnd::Time);
            }
            // A flash operation stalls the core: nothing executes until it ends.
            if let Some(t) = self.board().flash.busy_until.filter(|&t| t > now) {
                self.skip_to(t.min(self.next_event_or(until, now)));
                continue;
            }
            let primask = self.reg(RegisterARM::PRIMASK) & 1 != 0;
            let basepri = self.reg(RegisterARM::BASEPRI);
            if let Some(e) = self.board().nvic.next_to_take(primask, basepri) {
                self.enter(e)?;
                sleeping = false;
            } else if sleeping {
                // WFI/WFE wake on a pending interrupt even when masked by PRIMASK
                // (ARMv7-M B1.5.19); otherwise sleep until something happens.
                if self.board().nvic.any_pending() || self.board().event_reg {
                    sleeping = false;
                    self.board_mut().event_reg = false;
                } else {
                    let t = self.next_event_or(until, now);
                    self.skip_to(t);
                    continue;
                }
            }
            // Thread mode held (an injected stall): only handlers run.
            if let Some(h) = self.board().thread_hold_until {
                if self.board().nvic.stack.is_empty() {
                    if now >= h {
                        self.board_mut().thread_hold_until = None;
                    } else {
                        let t = self.next_event_or(until, now).min(h);
                        self.skip_to(t);
                        continue;
                    }
                }
            }
            let next = self.next_event_or(until, now);
            // An interrupt pending but masked by PRIMASK or BASEPRI (a critical section) is
            // taken on the core right after the instruction that unmasks it (CPSIE, MSR;
            // ARMv7-M B1.5.6, B5.2.3: these end the translation block in QEMU's TCG too):
            // run one block at a time until then, else the slice would run on to the next
            // peripheral event or MAX_SLICE (60 µs) and delay the interrupt by that much.
            // Only for MASKED_FINE: longer than that it is no critical section but code
            // that masks for good (a fault handler waiting for its reset), which then runs
            // in normal slices.
            if self.board().nvic.next_to_take(false, 0).is_some() {
                masked_since.get_or_insert(now);
            } else {
                masked_since = None;
            }
            let slice = match masked_since {
                Some(t) if now - t < MASKED_FINE => 1,
                _ => (next - now).clamp(1, MAX_SLICE),
            };
            {
                let b = self.board_mut();
                b.stop = None;
                b.stop_at = b.cycles + slice;
                b.deadline = now + slice;
            }
            let pc = self.uc.reg_read(RegisterARM::PC).map_err(uc_err)?;
            if let Some(p) = &mut self.profile {
                *p.entry(pc as u32).or_insert(0) += 1;
            }
            let r = self.uc.emu_start(pc | 1, 0, 0, 0);
            if let Err(e) = r {
                let pc = self.uc.reg_read(RegisterARM::PC).unwrap_or(0);
                let why = format!("{e:?} at pc {pc:#010x}");
                if let Some(end) = self.fault(why)? {
                    return Ok(end);
                }
                continue;
            }
            match self.board_mut().stop.take() {
                Some(Stop::Sleep { wfe, next }) => {
                    self.uc
                        .reg_write(RegisterARM::PC, u64::from(next | 1))
                        .map_err(uc_err)?;
                    if !wfe || !self.board().event_reg {
                        sleeping = true;
                    } else {
                        self.board_mut().event_reg = false;
                    }
                }
                Some(Stop::ExcReturn(ret)) => {
                    if self.board().nvic.stack.is_empty() {
                        if let Some(end) =
                            self.fault(format!("EXC_RETURN {ret:#x} in thread mode"))?
                        {
                            return Ok(end);
                        }
                    } else {
                        self.exc_return(ret)?;
                        // SLEEPONEXIT (SCR bit 1): back to sleep when the last handler ends.
                        if self.board().nvic.stack.is_empty() && self.board().nvic.scr & 2 != 0 {
                            sleeping = true;
                        }
                    }
                }
                Some(Stop::CoreException { intno, pc }) => {
                    if let Some(end) =
                        self.fault(format!("core exception {intno} at pc {pc:#010x}"))?
                    {
                        return Ok(end);
                    }
                }
                Some(Stop::Resched) | None => {}
            }
        }
    }

    fn next_event_or(&self, until: Cyc, now: Cyc) -> Cyc {
        self.board()
            .next_event(now)
            .unwrap_or(until)
            .min(until)
            .max(now)
    }

    /// Lets virtual time pass without instructions.
    fn skip_to(&mut self, t: Cyc) {
        let b = self.board_mut();
        let now = b.now();
        if t > now {
            b.skipped += t - now;
        } else {
            // Nothing scheduled sooner: move on by a microsecond so time cannot stand still.
            b.skipped += CPU_HZ / 1_000_000;
        }
    }

    /// Reads a NUL-free RAM region (for reports).
    pub fn mem(&self, addr: u32, len: usize) -> Option<Vec<u8>> {
        self.uc.mem_read_as_vec(u64::from(addr), len).ok()
    }

    /// Debugger-style: sets a core register.
    pub fn poke_reg(&mut self, r: RegisterARM, v: u32) {
        self.set_reg(r, v);
    }

    /// Debugger-style: reads a core register.
    pub fn peek_reg(&self, r: RegisterARM) -> u32 {
        self.reg(r)
    }

    /// Debugger-style: writes a word of RAM.
    pub fn poke32(&mut self, a: u32, v: u32) -> bool {
        self.write32(a, v)
    }

    /// Debugger-style: reads a word.
    pub fn peek32(&self, a: u32) -> u32 {
        self.read32(a)
    }

    /// The program counter.
    pub fn pc(&self) -> u32 {
        self.uc.reg_read(RegisterARM::PC).unwrap_or(0) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stub_jumps_like_the_bootloader() {
        let s = stub();
        assert_eq!(u32::from_le_bytes([s[0], s[1], s[2], s[3]]), 0x2002_0000);
        // The literal the first instruction loads sits at PC-aligned + 12.
        let lit = (STUB_ENTRY + 4) & !3;
        let o = (lit + 12 - 0x0800_0000) as usize;
        assert_eq!(
            u32::from_le_bytes([s[o], s[o + 1], s[o + 2], s[o + 3]]),
            IMAGE_BASE
        );
    }

    #[test]
    fn thumb_instructions_counted() {
        // movs r0, #1 ; ldr.w r1, [r0] ; bx lr
        assert_eq!(
            crate::cycles::cost(
                0x0800_8000,
                &[0x01, 0x20, 0xD0, 0xF8, 0x00, 0x10, 0x70, 0x47]
            )
            .insns,
            3
        );
    }

    #[test]
    fn special_instructions_found() {
        let img = [0x30, 0xBF, 0x20, 0xBF, 0xAF, 0xF3, 0x02, 0x80, 0x40, 0xBF];
        let s = scan_special(&img);
        let b = ((IMAGE_BASE - 0x0800_0000) / 2) as usize;
        assert_eq!(&s[b..b + 5], &[1, 2, 2, 0, 3]);
    }
}
