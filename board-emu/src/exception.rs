//! Exception entry and return for the core model (Unicorn has no NVIC): what `crate::cpu`'s
//! module comment describes, from ARMv7-M ARM B1.5.6 (entry, PushStack) and B1.5.8 (return,
//! PopStack), and the escalation of a fault the core met to HardFault (B1.5.1).

use crate::cpu::{uc_err, Emulator, RunEnd};
use crate::nvic::exc;
use anyhow::{anyhow, Result};
use unicorn_engine::RegisterARM;

impl Emulator<'_> {
    /// Takes exception `e` (ARMv7-M B1.5.6): pushes the frame, enters the handler.
    pub(crate) fn enter(&mut self, e: u16) -> Result<()> {
        let control = self.reg(RegisterARM::CONTROL);
        let fpca = control & 4 != 0;
        let in_thread = self.board().nvic.stack.is_empty();
        let use_psp = in_thread && control & 2 != 0;
        let sp_reg = if use_psp {
            RegisterARM::PSP
        } else {
            RegisterARM::MSP
        };
        let sp = self.reg(RegisterARM::SP);
        let frame = if fpca { 0x68 } else { 0x20 };
        let pad = (sp - frame) & 4 != 0;
        let new_sp = (sp - frame) & !7;
        let pc = self.uc.reg_read(RegisterARM::PC).map_err(uc_err)? as u32;
        let ipsr = u32::from(self.board().nvic.stack.last().copied().unwrap_or(0));
        let xpsr =
            (self.reg(RegisterARM::XPSR) & !0x1FF & !(1 << 9)) | ipsr | (u32::from(pad) << 9);
        let mut words = vec![
            self.reg(RegisterARM::R0),
            self.reg(RegisterARM::R1),
            self.reg(RegisterARM::R2),
            self.reg(RegisterARM::R3),
            self.reg(RegisterARM::R12),
            self.reg(RegisterARM::LR),
            pc & !1,
            xpsr | (1 << 24),
        ];
        if fpca {
            for i in 0..16 {
                let r = RegisterARM::S0 as i32 + i;
                words.push(self.uc.reg_read(r).unwrap_or(0) as u32);
            }
            words.push(self.reg(RegisterARM::FPSCR));
            words.push(0);
        }
        for (i, w) in words.iter().enumerate() {
            if !self.write32(new_sp + 4 * i as u32, *w) {
                return Err(anyhow!(
                    "exception {e}: stack push at {new_sp:#010x} failed"
                ));
            }
        }
        self.set_reg(sp_reg, new_sp);
        self.set_reg(RegisterARM::CONTROL, control & !(4 | 2));
        self.set_reg(RegisterARM::SP, new_sp);
        let exc_return = 0xFFFF_FFE1
            | (u32::from(!fpca) << 4)
            | (u32::from(in_thread) << 3)
            | (u32::from(use_psp) << 2);
        self.set_reg(RegisterARM::LR, exc_return);
        // A fresh EPSR: Thumb, no IT block in progress.
        self.set_reg(
            RegisterARM::XPSR,
            (xpsr & 0xF80F_0000 & !0x0600_FC00) | (1 << 24),
        );
        let handler = self.vector(e);
        let vtor = match self.board().nvic.vtor {
            0 => 0x0800_0000,
            v => v,
        };
        let b = self.board_mut();
        let acr = crate::cycles::Acr::from_reg(b.flash.acr());
        let c = b.clock.entry(vtor + 4 * u32::from(e), acr);
        b.cycles += c;
        if let Some(x) = b.busy_by_exc.get_mut(usize::from(e)) {
            *x += c;
        }
        b.nvic.activate(e);
        b.frame_sp.push(new_sp);
        b.event_reg = true;
        self.uc
            .reg_write(RegisterARM::PC, u64::from(handler | 1))
            .map_err(uc_err)?;
        Ok(())
    }

    /// Returns from the innermost exception (ARMv7-M B1.5.8) with EXC_RETURN `ret`.
    pub(crate) fn exc_return(&mut self, ret: u32) -> Result<()> {
        let b = self.board_mut();
        b.clock.exit();
        let done = b.nvic.deactivate();
        b.frame_sp.pop();
        b.event_reg = true;
        let _ = done;
        let to_thread = ret & 8 != 0;
        let use_psp = ret & 4 != 0;
        let extended = ret & 0x10 == 0;
        let sp_reg = if use_psp {
            RegisterARM::PSP
        } else {
            RegisterARM::MSP
        };
        let sp = self.reg(sp_reg);
        let w = |i: u32| self.read32(sp + 4 * i);
        let regs = [
            RegisterARM::R0,
            RegisterARM::R1,
            RegisterARM::R2,
            RegisterARM::R3,
            RegisterARM::R12,
            RegisterARM::LR,
        ];
        let vals: Vec<u32> = (0..8).map(w).collect();
        let fp: Vec<u32> = if extended {
            (8..26).map(w).collect()
        } else {
            Vec::new()
        };
        for (r, v) in regs.iter().zip(&vals) {
            self.set_reg(*r, *v);
        }
        let xpsr = vals[7];
        let frame = if extended { 0x68 } else { 0x20 };
        let new_sp = sp + frame + if xpsr & (1 << 9) != 0 { 4 } else { 0 };
        self.set_reg(sp_reg, new_sp);
        let mut control = self.reg(RegisterARM::CONTROL) & !(4 | 2);
        if to_thread && use_psp {
            control |= 2;
        }
        if extended {
            for (i, v) in fp.iter().take(16).enumerate() {
                let _ = self
                    .uc
                    .reg_write(RegisterARM::S0 as i32 + i as i32, u64::from(*v));
            }
            self.set_reg(RegisterARM::FPSCR, fp[16]);
            control |= 4;
        }
        self.set_reg(RegisterARM::CONTROL, control);
        self.set_reg(RegisterARM::SP, new_sp);
        // Flags, GE and the IT state come back; IPSR stays 0 for the core model.
        self.set_reg(RegisterARM::XPSR, xpsr & !0x1FF & !(1 << 9));
        self.set_reg(RegisterARM::XPSR_NZCVQG, xpsr);
        self.uc
            .reg_write(RegisterARM::PC, u64::from(vals[6] | 1))
            .map_err(uc_err)?;
        Ok(())
    }

    /// A fault the core met (unmapped access, undefined instruction): HardFault, or a lockup
    /// when it happens in the HardFault handler.
    pub(crate) fn fault(&mut self, why: String) -> Result<Option<RunEnd>> {
        let now = self.now();
        self.faults.push((now, why.clone()));
        if self.board().nvic.active[usize::from(exc::HARD_FAULT)] {
            return Ok(Some(RunEnd::Lockup(why)));
        }
        self.board_mut().nvic.hfsr |= 1 << 30; // FORCED
        self.enter(exc::HARD_FAULT)?;
        Ok(None)
    }
}
