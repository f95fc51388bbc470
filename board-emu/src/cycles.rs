//! The clock model: how many CPU cycles the code the core executes takes.
//!
//! Unicorn executes instructions and tells nothing of their time. Two models:
//!
//! * [`ClockModel::Ideal`] (the emulator's first model, kept to compare): one instruction is
//!   one cycle, exception entry and return take none.
//! * [`ClockModel::Chip`] (the default): each instruction costs what the Cortex-M4 TRM (ARM DDI
//!   0439, r0p1, §3.3.1 table 3-1 "Processor instruction set summary", and §7.2.3 table 7-1
//!   for the FPU) gives for zero-wait-state memory — PM0214, ST's programming manual for the
//!   same core, lists the instructions without cycle counts —, plus the flash wait states the
//!   image programs in FLASH_ACR.LATENCY (RM0090 §3.4.1 table 10: 5 at 168 MHz and 2.7–3.6 V)
//!   as the ART accelerator lets them through (RM0090 §3.4.2), plus exception entry, return
//!   and tail-chaining (Cortex-M4 TRM §3.3.1 "Interrupt latency", §5.5: 12 cycles to the
//!   handler's first instruction, 10 back, 6 between two handlers).
//!
//! Instruction costs (table 3-1; P, the pipeline refill, "1 to 3 depending on the alignment
//! and width of the target instruction"): data processing, moves, MUL/MLA/MLS, long
//! multiplies and the DSP multiplies 1; LDR/STR single 2, or 1 right after another single
//! load or store ("neighboring load and store single instructions can pipeline their address
//! and data phases"); LDRD/STRD 3; LDM/STM/PUSH/POP 1 + N registers; TBB/TBH 2; SDIV/UDIV 2
//! to 12 by the operands — taken as [`DIV_CYCLES`], since the operands are not known when a
//! block is costed —; a taken branch (any non-sequential next block: B, BL, BX, POP/LDR to
//! PC, TBB, a taken CBZ or conditional branch) adds P = 1, or 2 when its target is a 32-bit
//! instruction not on a word boundary; FPU (table 7-1): VADD/VSUB/VMUL/VCVT/VCMP/VMOV 1,
//! VMLA/VMLS/VFMA and their negated forms 3, VDIV/VSQRT 14, VLDR/VSTR 2, VLDM/VSTM/VPUSH/VPOP
//! 1 + N words.
//!
//! The ART accelerator (RM0090 §3.4.2, FLASH_ACR PRFTEN bit 8, ICEN bit 9, DCEN bit 10):
//! flash is read 128 bits (a line) at a time, LATENCY wait states per read. The line being
//! executed and, with prefetch, the next sequential line (whose read starts when the core
//! moves onto a line, "while the current instruction line is being requested") cost nothing
//! more once they have arrived; a line found in the instruction cache (64 lines of 128 bits,
//! least recently used replaced; "each time a miss occurs … the line read is copied into the
//! instruction cache memory") costs nothing; any other line costs the wait states. Literal
//! pools (PC-relative LDR/VLDR) are read over the D-Code bus through the data cache (8
//! lines, the same policy) and stall the pipeline on a miss. Code outside flash (none in the
//! image) runs without wait states.
//!
//! Not modelled: other data reads from flash (constant tables read through a register: they
//! would need a hook on every load, which halves the emulator's speed), the AHB/APB bridge
//! latency of peripheral registers (RM0090 gives none), bus contention with DMA, the cache
//! resets (ICRST/DCRST), late-arriving exceptions, and the FPU's lazy state preservation
//! (an extended frame costs what a basic one does, as when a handler uses no FPU register).

use crate::time::Cyc;
// The block costs and the caches' tags are looked up on every translation block: FxHash (the
// compiler's own hasher) instead of SipHash, which took a quarter of the emulator's time.
use rustc_hash::FxHashMap as HashMap;

/// Which clock model the emulator runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ClockModel {
    /// One instruction = one cycle, free exception entry and return (the first model).
    Ideal,
    /// Instruction timings, flash wait states through the ART accelerator, exception cycles.
    #[default]
    Chip,
}

/// SDIV/UDIV cycles taken (table 3-1: 2 to 12, "division operations use early termination
/// to minimize the number of cycles required based on the number of leading ones and zeroes
/// in the input operands").
pub const DIV_CYCLES: u32 = 7;
/// Exception entry to the handler's first instruction, cycles (zero wait states).
pub const ENTRY_CYCLES: Cyc = 12;
/// Exception return to the interrupted instruction, cycles.
pub const EXIT_CYCLES: Cyc = 10;
/// From one handler's return to the next pending handler's first instruction (tail-chaining).
pub const TAIL_CHAIN_CYCLES: Cyc = 6;

/// Code flash (sectors 0–11): fetched through the ART accelerator.
const FLASH: std::ops::Range<u32> = 0x0800_0000..0x0810_0000;

/// What one translation block costs, worked out once from its code.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BlockCost {
    /// Bytes of code.
    pub size: u32,
    /// Instructions.
    pub insns: u64,
    /// Cycles with zero-wait-state memory and the block's last branch not taken.
    pub base: u32,
    /// The 128-bit flash lines the block's instructions come from, in order, each with the
    /// cycles its instructions take (for the prefetch's overlap).
    pub lines: Vec<(u32, u32)>,
    /// Addresses of the literals its PC-relative loads read.
    pub literals: Vec<u32>,
    /// Its first instruction is 32-bit (a longer refill when it is not word-aligned).
    pub first_wide: bool,
}

/// One decoded instruction's timing class.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Class {
    /// A single load or store (pipelines with a neighbour).
    Single,
    /// Anything else, with its cycles.
    Other(u32),
}

/// The cost class of the Thumb-2 instruction `hw1` (`hw2`, its second halfword when 32-bit)
/// at `addr`, and the literal it reads if it is PC-relative (ARMv7-M ARM A5.2, A5.3 for the
/// encodings).
fn classify(addr: u32, hw1: u16, hw2: u16) -> (Class, Option<u32>) {
    let pc_align = (addr + 4) & !3;
    if hw1 >> 11 < 0b11101 {
        // 16-bit.
        return match hw1 >> 11 {
            // LDR (literal): 01001 Rt imm8.
            0b01001 => (Class::Single, Some(pc_align + u32::from(hw1 & 0xFF) * 4)),
            // Load/store register offset, immediate offset, SP-relative.
            0b01010..=0b10011 => (Class::Single, None),
            // STM/LDM: 1 + N.
            0b11000 | 0b11001 => (Class::Other(1 + (hw1 & 0xFF).count_ones()), None),
            // PUSH (1011 010x) / POP (1011 110x): 1 + N, LR/PC included.
            0b10110 | 0b10111 if hw1 & 0x0600 == 0x0400 => (
                Class::Other(1 + (hw1 & 0xFF).count_ones() + u32::from(hw1 >> 8 & 1)),
                None,
            ),
            _ => (Class::Other(1), None),
        };
    }
    let regs = |list: u16| u32::from(list).count_ones();
    match hw1 >> 11 {
        0b11101 => {
            if hw1 & 0xFE40 == 0xE800 {
                // LDM/STM (and PUSH/POP.W): 1 + N.
                (Class::Other(1 + regs(hw2)), None)
            } else if hw1 & 0xFE40 == 0xE840 {
                if hw1 & 0xFFF0 == 0xE8D0 && hw2 & 0xFFE0 == 0xF000 {
                    // TBB/TBH: 2 (+P when taken, always).
                    (Class::Other(2), None)
                } else if hw1 & 0x0120 != 0 || hw1 & 0x0180 == 0x0100 {
                    // LDRD/STRD: 1 + N (N = 2); the literal form reads PC-relative.
                    let lit = (hw1 & 0xF == 0xF && hw1 & 0x0100 != 0).then(|| {
                        let off = u32::from(hw2 & 0xFF) * 4;
                        if hw1 & 0x80 != 0 {
                            pc_align + off
                        } else {
                            pc_align.wrapping_sub(off)
                        }
                    });
                    (Class::Other(3), lit)
                } else {
                    // LDREX/STREX.
                    (Class::Other(2), None)
                }
            } else if hw1 & 0xEC00 == 0xEC00 {
                fp(pc_align, hw1, hw2)
            } else {
                (Class::Other(1), None)
            }
        }
        0b11110 => (Class::Other(1), None),
        _ => {
            // 0b11111.
            if hw1 & 0xFE00 == 0xF800 {
                // Load/store single (byte, halfword, word); Rn = PC with a load: the literal.
                let load = hw1 & 0x10 != 0;
                let lit = (load && hw1 & 0xF == 0xF).then(|| {
                    let off = u32::from(hw2 & 0xFFF);
                    if hw1 & 0x80 != 0 {
                        pc_align + off
                    } else {
                        pc_align.wrapping_sub(off)
                    }
                });
                (Class::Single, lit)
            } else if hw1 & 0xFFD0 == 0xFB90 && hw2 & 0xF0 == 0xF0 {
                // SDIV (FB90) / UDIV (FBB0).
                (Class::Other(DIV_CYCLES), None)
            } else if hw1 & 0xEC00 == 0xEC00 {
                fp(pc_align, hw1, hw2)
            } else {
                // Data processing (register), multiplies, long multiplies: 1.
                (Class::Other(1), None)
            }
        }
    }
}

/// FPU instructions (Cortex-M4 TRM table 7-1) in the coprocessor space 111x 11xx.
fn fp(pc_align: u32, hw1: u16, hw2: u16) -> (Class, Option<u32>) {
    if hw1 & 0x0E00 == 0x0C00 || hw1 & 0x0F00 == 0x0D00 {
        // Extension register load/store (1110 110x / 1110 1101).
        if hw1 & 0x0F20 == 0x0D00 {
            // VLDR/VSTR: 2; the literal form (Rn = PC, load) reads PC-relative.
            let lit = (hw1 & 0x10 != 0 && hw1 & 0xF == 0xF).then(|| {
                let off = u32::from(hw2 & 0xFF) * 4;
                if hw1 & 0x80 != 0 {
                    pc_align + off
                } else {
                    pc_align.wrapping_sub(off)
                }
            });
            return (Class::Other(2), lit);
        }
        // VLDM/VSTM/VPUSH/VPOP: 1 + the words moved (imm8).
        return (Class::Other(1 + u32::from(hw2 & 0xFF)), None);
    }
    if hw1 & 0x0F00 == 0x0E00 && hw2 & 0x0E00 == 0x0A00 && hw2 & 0x10 == 0 {
        // VFP data processing: opc1 = hw1[7:4] with bits 6 and 4 of it (A6.4 table).
        let opc1 = (hw1 >> 4) & 0xB;
        let cycles = match opc1 {
            // VMLA/VMLS, VNMLA/VNMLS, VFMA/VFMS, VFNMA/VFNMS: 3.
            0b0000 | 0b0001 | 0b1001 => 3,
            // VDIV: 14.
            0b1000 => 14,
            // VSQRT (opc2 0001, opc3 11).
            0b1011 if hw1 & 0xF == 0x1 && hw2 & 0xC0 == 0xC0 => 14,
            _ => 1,
        };
        return (Class::Other(cycles), None);
    }
    (Class::Other(1), None)
}

/// Works out what the block of Thumb-2 `code` at `addr` costs (see the module documentation).
pub fn cost(addr: u32, code: &[u8]) -> BlockCost {
    let hw = |i: usize| {
        code.get(i..i + 2)
            .map_or(0, |b| u16::from_le_bytes([b[0], b[1]]))
    };
    let mut c = BlockCost {
        size: code.len() as u32,
        ..Default::default()
    };
    let mut i = 0;
    let mut prev_single = false;
    while i + 1 < code.len() {
        let a = addr + i as u32;
        let hw1 = hw(i);
        let wide = hw1 >> 11 >= 0b11101;
        let hw2 = if wide { hw(i + 2) } else { 0 };
        if i == 0 {
            c.first_wide = wide;
        }
        let (class, lit) = classify(a, hw1, hw2);
        let cycles = match class {
            Class::Single if prev_single => 1,
            Class::Single => 2,
            Class::Other(n) => n,
        };
        prev_single = class == Class::Single;
        let line = a & !15;
        match c.lines.last_mut() {
            Some((l, n)) if *l == line => *n += cycles,
            _ => c.lines.push((line, cycles)),
        }
        // A 32-bit instruction straddling two lines needs the second one too.
        if wide && (a + 2) & !15 != line {
            c.lines.push(((a + 2) & !15, 0));
        }
        if let Some(l) = lit {
            c.literals.push(l);
        }
        c.base += cycles;
        c.insns += 1;
        i += if wide { 4 } else { 2 };
    }
    c.insns = c.insns.max(1);
    c
}

/// A fully associative cache of 128-bit lines, least recently used replaced.
#[derive(Clone, Debug)]
struct Lines {
    tags: Vec<u32>,
    used: Vec<u64>,
    /// Slot + 1 of each flash line held (0: not held), by line number in flash.
    slot: Vec<u8>,
    tick: u64,
}

/// 128-bit lines in the code flash.
const FLASH_LINES: usize = ((FLASH.end - FLASH.start) / 16) as usize;

impl Lines {
    fn new(n: usize) -> Self {
        Lines {
            tags: vec![u32::MAX; n],
            used: vec![0; n],
            slot: vec![0; FLASH_LINES],
            tick: 0,
        }
    }

    /// Whether the flash line at `line` is held (marking it used); a miss copies it in.
    fn access(&mut self, line: u32) -> bool {
        self.tick += 1;
        let k = (line.wrapping_sub(FLASH.start) / 16) as usize;
        let Some(&held) = self.slot.get(k) else {
            return false;
        };
        if held != 0 {
            self.used[usize::from(held - 1)] = self.tick;
            return true;
        }
        let s = (0..self.used.len())
            .min_by_key(|&s| self.used[s])
            .unwrap_or(0);
        if self.tags[s] != u32::MAX {
            let old = (self.tags[s].wrapping_sub(FLASH.start) / 16) as usize;
            if let Some(o) = self.slot.get_mut(old) {
                *o = 0;
            }
        }
        self.tags[s] = line;
        self.used[s] = self.tick;
        self.slot[k] = s as u8 + 1;
        false
    }

    fn clear(&mut self) {
        *self = Lines::new(self.tags.len());
    }
}

/// The ART accelerator's state: the line in use, the prefetched one and the two caches.
#[derive(Clone, Debug)]
struct Art {
    current: Option<u32>,
    /// The next line being read ahead, and when it is in.
    prefetch: Option<(u32, Cyc)>,
    icache: Lines,
    dcache: Lines,
}

/// FLASH_ACR as the ART sees it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Acr {
    /// LATENCY (bits 2:0): wait states.
    pub wait_states: u32,
    /// PRFTEN (bit 8).
    pub prefetch: bool,
    /// ICEN (bit 9).
    pub icache: bool,
    /// DCEN (bit 10).
    pub dcache: bool,
}

impl Acr {
    /// From the register's value (RM0090 §3.9.1).
    pub fn from_reg(v: u32) -> Self {
        Acr {
            wait_states: v & 7,
            prefetch: v & (1 << 8) != 0,
            icache: v & (1 << 9) != 0,
            dcache: v & (1 << 10) != 0,
        }
    }
}

impl Art {
    fn new() -> Self {
        Art {
            current: None,
            prefetch: None,
            icache: Lines::new(64),
            dcache: Lines::new(8),
        }
    }

    /// The stall, cycles, of moving the instruction fetch onto `line` at `t`.
    fn fetch(&mut self, line: u32, t: Cyc, acr: Acr) -> Cyc {
        if !FLASH.contains(&line) {
            self.current = None;
            return 0;
        }
        if self.current == Some(line) {
            return 0;
        }
        let ws = Cyc::from(acr.wait_states);
        let stall = match self.prefetch {
            Some((l, ready)) if l == line => ready.saturating_sub(t),
            _ if acr.icache && self.icache.access(line) => 0,
            _ => ws,
        };
        self.current = Some(line);
        self.prefetch = acr.prefetch.then_some((line + 16, t + stall + ws + 1));
        stall
    }

    /// The stall of a D-Code read of `addr` (a literal).
    fn data(&mut self, addr: u32, acr: Acr) -> Cyc {
        if !FLASH.contains(&addr) {
            return 0;
        }
        if acr.dcache && self.dcache.access(addr & !15) {
            0
        } else {
            Cyc::from(acr.wait_states)
        }
    }
}

/// The clock: costs of blocks (cached by address) and the ART's state.
#[derive(Clone, Debug)]
pub struct Clock {
    /// The model in use.
    pub model: ClockModel,
    /// Block costs, and where each is: by halfword in flash (index + 1; 0 none), else by
    /// address (code in RAM).
    blocks: Vec<BlockCost>,
    in_flash: Vec<u32>,
    elsewhere: HashMap<u32, u32>,
    art: Art,
    /// Where the previous block ended (a block starting elsewhere follows a taken branch).
    last_end: u32,
    /// The next block follows an exception entry or return (its refill is in their cost).
    after_exception: bool,
    /// An exception return not yet charged: charged with the next block, or replaced by a
    /// tail-chain when the next thing the core does is another exception entry.
    exit_pending: bool,
    /// Cycles charged beyond the ideal model's one per instruction: wait states (of which
    /// literal reads: `literal_wait_cycles`).
    pub wait_cycles: Cyc,
    /// Wait states of literal reads over the D-Code bus.
    pub literal_wait_cycles: Cyc,
    /// … pipeline refills of taken branches.
    pub refill_cycles: Cyc,
    /// … exception entries and returns.
    pub exception_cycles: Cyc,
}

impl Clock {
    /// A clock of `model` with cold caches.
    pub fn new(model: ClockModel) -> Self {
        Clock {
            model,
            blocks: Vec::new(),
            in_flash: vec![0; ((FLASH.end - FLASH.start) / 2) as usize],
            elsewhere: HashMap::default(),
            art: Art::new(),
            last_end: 0,
            after_exception: false,
            exit_pending: false,
            wait_cycles: 0,
            literal_wait_cycles: 0,
            refill_cycles: 0,
            exception_cycles: 0,
        }
    }

    /// A reset: the caches and the prefetch are empty again (the costed blocks stay: the
    /// code did not change).
    pub fn reset(&mut self) {
        self.art = Art::new();
        self.art.icache.clear();
        self.last_end = 0;
        self.after_exception = false;
        self.exit_pending = false;
    }

    /// The index of the block at `addr` in `blocks`.
    fn lookup(&self, addr: u32) -> Option<usize> {
        let k = (addr.wrapping_sub(FLASH.start) / 2) as usize;
        match self.in_flash.get(k) {
            Some(&i) => i.checked_sub(1).map(|i| i as usize),
            None => self.elsewhere.get(&addr).map(|&i| i as usize),
        }
    }

    /// Keeps the cost of a block (replacing the one at the same address).
    pub fn learn(&mut self, addr: u32, cost: BlockCost) {
        let i = match self.lookup(addr) {
            Some(i) => {
                self.blocks[i] = cost;
                i
            }
            None => {
                self.blocks.push(cost);
                self.blocks.len() - 1
            }
        };
        let k = (addr.wrapping_sub(FLASH.start) / 2) as usize;
        match self.in_flash.get_mut(k) {
            Some(slot) => *slot = i as u32 + 1,
            None => {
                self.elsewhere.insert(addr, i as u32);
            }
        }
    }

    /// The block at `addr` of `size` bytes runs from busy cycle `t`: its instructions and
    /// cycles, or None when it is not costed yet ([`Clock::learn`] it, then ask again).
    pub fn run_block(&mut self, addr: u32, size: u32, t: Cyc, acr: Acr) -> Option<(u64, Cyc)> {
        let b = &self.blocks[self.lookup(addr)?];
        if b.size != size {
            return None;
        }
        if self.model == ClockModel::Ideal {
            return Some((b.insns, b.insns));
        }
        let mut cycles = Cyc::from(b.base);
        // A block that does not follow on from the last one: the branch to it was taken.
        if addr != self.last_end && !self.after_exception {
            let p = if addr & 2 != 0 && b.first_wide { 2 } else { 1 };
            cycles += p;
            self.refill_cycles += p;
        }
        if std::mem::take(&mut self.exit_pending) {
            cycles += EXIT_CYCLES;
            self.exception_cycles += EXIT_CYCLES;
        }
        self.after_exception = false;
        self.last_end = addr + size;
        let mut local = 0;
        let mut stall = 0;
        for &(line, n) in &b.lines {
            stall += self.art.fetch(line, t + local + stall, acr);
            local += Cyc::from(n);
        }
        for &l in &b.literals {
            let s = self.art.data(l, acr);
            self.literal_wait_cycles += s;
            stall += s;
        }
        self.wait_cycles += stall;
        Some((b.insns, cycles + stall))
    }

    /// Exception entry through `vector_addr` (the vector read over the D-Code bus): its
    /// cycles, tail-chained when nothing ran since the last return.
    pub fn entry(&mut self, vector_addr: u32, acr: Acr) -> Cyc {
        if self.model == ClockModel::Ideal {
            return 0;
        }
        self.after_exception = true;
        let vec_stall = self.art.data(vector_addr, acr);
        self.wait_cycles += vec_stall;
        let c = if std::mem::take(&mut self.exit_pending) {
            TAIL_CHAIN_CYCLES
        } else {
            ENTRY_CYCLES
        };
        self.exception_cycles += c;
        c + vec_stall
    }

    /// An exception return: charged with what the core does next (see `exit_pending`).
    pub fn exit(&mut self) {
        if self.model == ClockModel::Ideal {
            return;
        }
        self.after_exception = true;
        self.exit_pending = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn code(hws: &[u16]) -> Vec<u8> {
        hws.iter().flat_map(|h| h.to_le_bytes()).collect()
    }

    #[test]
    fn table_3_1_costs() {
        // movs r0,#1 (1); ldr r1,[r0] (2); str r1,[r0,#4] (1: pipelined); push {r4,lr} (3);
        // udiv r0,r1,r2 (DIV); bx lr (1).
        let c = cost(
            0x0800_8000,
            &code(&[0x2001, 0x6801, 0x6041, 0xB510, 0xFBB1, 0xF0F2, 0x4770]),
        );
        assert_eq!(c.insns, 6);
        assert_eq!(c.base, 1 + 2 + 1 + 3 + DIV_CYCLES + 1);
    }

    #[test]
    fn literal_loads_are_found() {
        // ldr r0, [pc, #8] at 0x0800_8002: Align(0x0800_8006, 4) + 8.
        let c = cost(0x0800_8002, &code(&[0x4802]));
        assert_eq!(c.literals, vec![0x0800_8004 + 8]);
        // ldr.w r0, [pc, #-4] at 0x0800_8000: Align(0x0800_8004) - 4.
        let c = cost(0x0800_8000, &code(&[0xF85F, 0x0004]));
        assert_eq!(c.literals, vec![0x0800_8000]);
    }

    #[test]
    fn fpu_costs() {
        // vdiv.f32 s0, s0, s1 (EE80 0A20): 14; vmla.f32 s0, s1, s2 (EE00 0A81): 3;
        // vadd.f32 (EE30 0A20): 1; vldr s0, [r0] (ED90 0A00): 2; vpush {s16-s17}
        // (ED2D 8A02): 3.
        let c = cost(
            0x0800_8000,
            &code(&[
                0xEE80, 0x0A20, 0xEE00, 0x0A81, 0xEE30, 0x0A20, 0xED90, 0x0A00, 0xED2D, 0x8A02,
            ]),
        );
        assert_eq!(c.base, 14 + 3 + 1 + 2 + 3);
    }

    #[test]
    fn wait_states_through_the_art() {
        let acr = Acr::from_reg(5 | 1 << 8 | 1 << 9 | 1 << 10);
        let mut clk = Clock::new(ClockModel::Chip);
        // Two lines of sixteen 1-cycle instructions (movs), a loop back to the first.
        let body: Vec<u16> = vec![0x2001; 16];
        clk.learn(0x0800_8000, cost(0x0800_8000, &code(&body)));
        // First run: the first line misses (5), the second was prefetched while the first
        // ran its 8 cycles (read in 6 after the first arrived: no stall).
        let (_, c1) = clk.run_block(0x0800_8000, 32, 0, acr).unwrap();
        assert_eq!(c1, 16 + 1 + 5);
        // Again (a branch back): the first line is in the cache now; the second was only
        // prefetched (not cached) and comes 6 cycles after the first line starts.
        let (_, c2) = clk.run_block(0x0800_8000, 32, 100, acr).unwrap();
        assert_eq!(c2, 16 + 1);
        // The ideal model: one cycle an instruction.
        clk.model = ClockModel::Ideal;
        assert_eq!(clk.run_block(0x0800_8000, 32, 200, acr), Some((16, 16)));
    }

    #[test]
    fn tail_chaining_costs_six() {
        let acr = Acr::default();
        let mut clk = Clock::new(ClockModel::Chip);
        clk.exit();
        assert_eq!(clk.entry(0x2000_0000, acr), TAIL_CHAIN_CYCLES);
        assert_eq!(clk.entry(0x2000_0000, acr), ENTRY_CYCLES);
        // A return followed by code: the return's cycles come with the block.
        clk.learn(0x2000_0000, cost(0x2000_0000, &code(&[0x2001])));
        clk.exit();
        assert_eq!(
            clk.run_block(0x2000_0000, 2, 0, acr).map(|r| r.1),
            Some(1 + EXIT_CYCLES)
        );
    }
}
