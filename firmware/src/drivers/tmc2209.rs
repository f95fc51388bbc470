//! TMC2209 stepper drivers over their single-wire UART: datagrams with CRC8, the registers this
//! firmware sets (GCONF, CHOPCONF, IHOLD_IRUN, TPWMTHRS, TPOWERDOWN), run/hold current from mA
//! and the sense resistor, stealthChop/spreadCycle, and a read-back that says whether the driver
//! answers and holds what was written.
//!
//! The wire format is the datasheet's (TMC2209 datasheet rev. 1.09, §4 "UART single wire
//! interface"): a write is `0x05, address, register | 0x80, 4 data bytes MSB first, CRC`; a read
//! request `0x05, address, register, CRC`; the reply `0x05, 0xFF, register, 4 data bytes, CRC`.
//! CRC8 with polynomial x⁸ + x² + x + 1, each byte shifted in LSB first (datasheet §4.2).
//!
//! On the SKR 2 each driver socket has its own single-wire line to PDN_UART, so every driver
//! answers at address 0 (MS1 = MS2 = low with BigTreeTech's UART jumpers): X on PE0, Y on PD3,
//! Z on PD0, E0 on PC6 (Marlin `pins_BTT_SKR_V2_0_common.h`: `X_SERIAL_TX_PIN PE0`,
//! `X_SERIAL_RX_PIN X_SERIAL_TX_PIN`, ...; Klipper `generic-bigtreetech-skr-2.cfg`: `uart_pin:
//! PE0`, `PD3`, `PD0`, `PC6`). Marlin drives them by software serial at 19200 Bd
//! (`TMC_BAUD_RATE 19200`), as [`SoftUart`] does.
//!
//! Why not the `tmc2209` crate (0.3): its register bitfields are good (the tests use it as an
//! independent check of the bytes this module sends), but its read path converts wire values with
//! `unreachable!()` and `loop {}` on unexpected input and its blocking reader has no timeout,
//! while a silent or garbled driver is exactly the case this firmware must report. The datagram
//! layer is a few dozen lines.

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};

/// Sync nibble and reserved bits that start every datagram.
pub const SYNC: u8 = 0x05;
/// The address replies are sent to.
pub const MASTER_ADDR: u8 = 0xFF;
/// Length of a write datagram and of a read reply, bytes.
pub const WRITE_LEN: usize = 8;
/// Length of a read request, bytes.
pub const READ_LEN: usize = 4;
/// The version the TMC2209 reports in IOIN bits 31..24.
pub const VERSION: u8 = 0x21;
/// Sense resistors on BigTreeTech's TMC2209 modules, ohms (Marlin `R_SENSE 0.11` in the SKR 2
/// and Ender-3 TMC2209 example `Configuration_adv.h`; Klipper's default `sense_resistor: 0.110`
/// for the TMC2209, `docs/Config_Reference.md`).
pub const RSENSE_OHM: f32 = 0.11;
/// The driver's internal clock, Hz (datasheet: 12 MHz nominal), for TPWMTHRS.
pub const FCLK_HZ: f32 = 12.0e6;

/// Register addresses (datasheet §5).
pub mod reg {
    /// Global configuration.
    pub const GCONF: u8 = 0x00;
    /// Global status (reset, driver error, undervoltage; write 1 to clear).
    pub const GSTAT: u8 = 0x01;
    /// Count of valid write datagrams received (8 bits, wraps).
    pub const IFCNT: u8 = 0x02;
    /// Input pins and version.
    pub const IOIN: u8 = 0x06;
    /// Run and hold current.
    pub const IHOLD_IRUN: u8 = 0x10;
    /// Delay before the current drops to hold at standstill.
    pub const TPOWERDOWN: u8 = 0x11;
    /// Upper stealthChop velocity (as TSTEP): above it the driver switches to spreadCycle.
    pub const TPWMTHRS: u8 = 0x13;
    /// Chopper configuration (off time, hysteresis, microsteps, vsense).
    pub const CHOPCONF: u8 = 0x6C;
    /// Driver status (temperature flags, shorts, open load, actual current).
    pub const DRV_STATUS: u8 = 0x6F;
}

/// GCONF bits.
pub mod gconf {
    /// Current reference from VREF (1) or internal (0).
    pub const I_SCALE_ANALOG: u32 = 1 << 0;
    /// spreadCycle (1) or stealthChop (0).
    pub const EN_SPREADCYCLE: u32 = 1 << 2;
    /// PDN_UART is the UART only (its power-down function off).
    pub const PDN_DISABLE: u32 = 1 << 6;
    /// Microsteps from CHOPCONF.MRES instead of the MS1/MS2 pins.
    pub const MSTEP_REG_SELECT: u32 = 1 << 7;
    /// Step pulse filter.
    pub const MULTISTEP_FILT: u32 = 1 << 8;
}

/// The CRC8 of a datagram's bytes (datasheet §4.2).
pub fn crc8(bytes: &[u8]) -> u8 {
    let mut crc = 0u8;
    for &b in bytes {
        let mut byte = b;
        for _ in 0..8 {
            crc = if (crc >> 7) ^ (byte & 1) != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
            byte >>= 1;
        }
    }
    crc
}

/// The write datagram for `value` into `register` of the driver at `addr`.
pub fn write_datagram(addr: u8, register: u8, value: u32) -> [u8; WRITE_LEN] {
    let d = value.to_be_bytes();
    let mut g = [SYNC, addr, register | 0x80, d[0], d[1], d[2], d[3], 0];
    g[7] = crc8(&g[..7]);
    g
}

/// The read request for `register` of the driver at `addr`.
pub fn read_request(addr: u8, register: u8) -> [u8; READ_LEN] {
    let mut g = [SYNC, addr, register & 0x7F, 0];
    g[3] = crc8(&g[..3]);
    g
}

/// Why a register could not be read or written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TmcError {
    /// Fewer bytes than a reply came back before the timeout (bytes received).
    NoReply(u8),
    /// The reply's CRC is wrong.
    BadCrc,
    /// The reply does not start with sync and the master address, or names another register.
    BadReply,
    /// A write was not counted by the driver (IFCNT did not advance).
    WriteNotCounted,
    /// The register reads back another value than written (register, value read).
    Mismatch(u8, u32),
    /// IOIN reports another chip version (not a TMC2209).
    Version(u8),
}

impl core::fmt::Display for TmcError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TmcError::NoReply(0) => write!(f, "no answer on UART"),
            TmcError::NoReply(n) => write!(f, "reply cut short ({n} of 8 bytes)"),
            TmcError::BadCrc => write!(f, "reply with a wrong CRC"),
            TmcError::BadReply => write!(f, "malformed reply"),
            TmcError::WriteNotCounted => write!(f, "write not acknowledged (IFCNT)"),
            TmcError::Mismatch(r, v) => write!(f, "register 0x{r:02X} reads back 0x{v:08X}"),
            TmcError::Version(v) => write!(f, "version 0x{v:02X}, not a TMC2209"),
        }
    }
}

/// Checks a reply to a read of `register` and returns its value.
pub fn parse_reply(reply: &[u8; WRITE_LEN], register: u8) -> Result<u32, TmcError> {
    if crc8(&reply[..7]) != reply[7] {
        return Err(TmcError::BadCrc);
    }
    if reply[0] & 0x0F != SYNC || reply[1] != MASTER_ADDR || reply[2] != register & 0x7F {
        return Err(TmcError::BadReply);
    }
    Ok(u32::from_be_bytes([reply[3], reply[4], reply[5], reply[6]]))
}

/// One driver's single-wire UART, half duplex: what [`send`](SingleWire::send) puts on the
/// line is not received back (an implementation on a shared TX/RX line ignores its own echo).
pub trait SingleWire {
    /// Sends `bytes`, then releases the line for the driver's reply.
    fn send(&mut self, bytes: &[u8]);
    /// Receives up to `buf.len()` bytes, each within the reply timeout of the previous one (or
    /// of the call); returns how many arrived.
    fn receive(&mut self, buf: &mut [u8]) -> usize;
}

/// Register access to one driver.
pub struct Tmc2209<W: SingleWire> {
    wire: W,
    addr: u8,
}

impl<W: SingleWire> Tmc2209<W> {
    /// The driver at `addr` (0 on the SKR 2) on `wire`.
    pub fn new(wire: W, addr: u8) -> Self {
        Tmc2209 { wire, addr }
    }

    /// The wire (tests inspect their driver model through it).
    pub fn wire_mut(&mut self) -> &mut W {
        &mut self.wire
    }

    /// Reads a register.
    pub fn read(&mut self, register: u8) -> Result<u32, TmcError> {
        self.wire.send(&read_request(self.addr, register));
        let mut reply = [0u8; WRITE_LEN];
        let n = self.wire.receive(&mut reply);
        if n < WRITE_LEN {
            return Err(TmcError::NoReply(n as u8));
        }
        parse_reply(&reply, register)
    }

    /// Writes a register (the driver does not answer writes: see [`Self::write_checked`]).
    pub fn write(&mut self, register: u8, value: u32) {
        self.wire.send(&write_datagram(self.addr, register, value));
    }

    /// Writes a register and checks that the driver counted it (IFCNT advanced by one).
    pub fn write_checked(&mut self, register: u8, value: u32) -> Result<(), TmcError> {
        let before = self.read(reg::IFCNT)? & 0xFF;
        self.write(register, value);
        let after = self.read(reg::IFCNT)? & 0xFF;
        if after != (before + 1) & 0xFF {
            return Err(TmcError::WriteNotCounted);
        }
        Ok(())
    }

    /// Writes every register of `settings`, checks each write was counted, reads back GCONF
    /// and CHOPCONF and the chip version, and clears GSTAT. Motion must stay disabled unless
    /// this returns `Ok`.
    pub fn configure(&mut self, settings: &DriverSettings) -> Result<(), TmcError> {
        let version = (self.read(reg::IOIN)? >> 24) as u8;
        if version != VERSION {
            return Err(TmcError::Version(version));
        }
        let regs = settings.registers();
        for &(r, v) in regs.iter() {
            self.write_checked(r, v)?;
        }
        for &(r, v) in regs.iter() {
            if r == reg::GCONF || r == reg::CHOPCONF {
                let got = self.read(r)?;
                if got != v {
                    return Err(TmcError::Mismatch(r, got));
                }
            }
        }
        // Reset / error flags from power-up are cleared by writing 1s.
        self.write_checked(reg::GSTAT, 0b111)
    }

    /// The driver's state for M122.
    pub fn report(&mut self) -> Result<DriverReport, TmcError> {
        Ok(DriverReport {
            gconf: self.read(reg::GCONF)?,
            chopconf: self.read(reg::CHOPCONF)?,
            drv_status: self.read(reg::DRV_STATUS)?,
            gstat: self.read(reg::GSTAT)?,
        })
    }
}

/// What one driver is set to: microsteps, currents, chopper mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriverSettings {
    /// Microsteps per full step (1, 2, 4, ..., 256).
    pub microsteps: u16,
    /// Run current, mA RMS.
    pub run_ma: u16,
    /// Hold current as a fraction of the run current (Marlin's `HOLD_MULTIPLIER 0.5`).
    pub hold_fraction: f32,
    /// stealthChop (quiet) instead of spreadCycle.
    pub stealthchop: bool,
    /// With stealthChop: switch to spreadCycle above this TSTEP-based threshold (register
    /// TPWMTHRS; 0 = stealthChop at every speed). See [`tpwmthrs`].
    pub tpwmthrs: u32,
    /// Sense resistor, ohms.
    pub rsense_ohm: f32,
}

impl DriverSettings {
    /// An Ender-3 axis on BigTreeTech's TMC2209 module: 16 microsteps, stealthChop at every
    /// speed (Marlin's TMC Ender-3 examples: `STEALTHCHOP_XY`, `STEALTHCHOP_Z`,
    /// `STEALTHCHOP_E`), hold at half the run current, `run_ma` as given.
    pub const fn ender3(run_ma: u16) -> DriverSettings {
        DriverSettings {
            microsteps: 16,
            run_ma,
            hold_fraction: 0.5,
            stealthchop: true,
            tpwmthrs: 0,
            rsense_ohm: RSENSE_OHM,
        }
    }

    /// The settings of `axis`'s driver in `cfg`: its microsteps, M906 current and M569 mode,
    /// BigTreeTech's 0.11 Ω sense resistor, hold at half the run current.
    pub fn of_axis(cfg: &crate::config::MachineConfig, axis: crate::motion::Axis) -> Self {
        let i = axis.index();
        let mut s = Self::ender3(cfg.driver_current_ma[i]);
        s.microsteps = cfg.axes[i].microsteps;
        s.stealthchop = cfg.driver_stealthchop[i];
        s
    }

    /// The register values, in the order they are written.
    pub fn registers(&self) -> [(u8, u32); 5] {
        let (vsense, irun) = current_scale(self.run_ma, self.rsense_ohm);
        let hold = libm::roundf(f32::from(irun + 1) * self.hold_fraction.clamp(0.0, 1.0)) as u8;
        let ihold = hold.saturating_sub(1).min(31);
        let mut gconf = gconf::PDN_DISABLE | gconf::MSTEP_REG_SELECT | gconf::MULTISTEP_FILT;
        if !self.stealthchop {
            gconf |= gconf::EN_SPREADCYCLE;
        }
        // Marlin's TMC2209 chopper: TOFF 4 (CHOPPER_DEFAULT_24V: toff 4, hend -1, hstrt 1 → HEND
        // 2, HSTRT 0), TBL 1, interpolation to 256 microsteps.
        let mut chopconf: u32 = 4 | (2 << 7) | (1 << 15) | (1 << 28);
        chopconf |= u32::from(mres(self.microsteps)) << 24;
        if vsense {
            chopconf |= 1 << 17;
        }
        let ihold_irun = u32::from(ihold) | (u32::from(irun) << 8) | (10 << 16);
        [
            (reg::GCONF, gconf),
            (reg::CHOPCONF, chopconf),
            (reg::IHOLD_IRUN, ihold_irun),
            (reg::TPOWERDOWN, 128),
            (reg::TPWMTHRS, self.tpwmthrs.min((1 << 20) - 1)),
        ]
    }
}

/// CHOPCONF.MRES for `microsteps` (256 → 0, 16 → 4, 1 → 8); anything not a power of two up to
/// 256 rounds down to one.
pub fn mres(microsteps: u16) -> u8 {
    let m = microsteps.clamp(1, 256);
    8 - (15 - m.leading_zeros()) as u8
}

/// Microsteps for a CHOPCONF.MRES value.
pub fn microsteps_of(mres: u8) -> u16 {
    256u16 >> mres.min(8)
}

/// (vsense, current scale 0..=31) for `ma` RMS through `rsense_ohm` (datasheet §9: I_RMS =
/// (CS + 1)/32 · V_FS/(R_SENSE + 20 mΩ) · 1/√2, V_FS 0.325 V, or 0.180 V with vsense; the high
/// sensitivity range is used when it gives the finer setting, as Marlin's TMCStepper does).
pub fn current_scale(ma: u16, rsense_ohm: f32) -> (bool, u8) {
    let amps = f32::from(ma) / 1000.0;
    let cs = |vfs: f32| 32.0 * core::f32::consts::SQRT_2 * amps * (rsense_ohm + 0.02) / vfs - 1.0;
    let low = cs(0.325);
    if low < 16.0 {
        (true, cs(0.180).clamp(0.0, 31.0) as u8)
    } else {
        (false, low.clamp(0.0, 31.0) as u8)
    }
}

/// The RMS current, mA, a (vsense, current scale) pair gives.
pub fn current_ma(vsense: bool, cs: u8, rsense_ohm: f32) -> f32 {
    let vfs = if vsense { 0.180 } else { 0.325 };
    (f32::from(cs) + 1.0) / 32.0 * vfs / (rsense_ohm + 0.02) / core::f32::consts::SQRT_2 * 1000.0
}

/// TPWMTHRS for a switch from stealthChop to spreadCycle at `mm_s` on an axis of
/// `steps_per_mm` at `microsteps` (TSTEP counts 1/256 microsteps: TSTEP = fclk /
/// (v · steps_per_mm · 256 / microsteps); Marlin's `_tmc_thrs`). 0 for a non-positive speed.
pub fn tpwmthrs(mm_s: f32, steps_per_mm: f32, microsteps: u16) -> u32 {
    let f = mm_s * steps_per_mm * 256.0 / f32::from(microsteps.max(1));
    if f.is_nan() || f <= 0.0 || !f.is_finite() {
        return 0;
    }
    (FCLK_HZ / f).min(((1u32 << 20) - 1) as f32) as u32
}

/// A driver's registers for M122.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DriverReport {
    /// GCONF.
    pub gconf: u32,
    /// CHOPCONF.
    pub chopconf: u32,
    /// DRV_STATUS.
    pub drv_status: u32,
    /// GSTAT.
    pub gstat: u32,
}

impl DriverReport {
    /// Microsteps set in CHOPCONF.
    pub fn microsteps(&self) -> u16 {
        microsteps_of(((self.chopconf >> 24) & 0xF) as u8)
    }
    /// stealthChop selected in GCONF.
    pub fn stealthchop(&self) -> bool {
        self.gconf & gconf::EN_SPREADCYCLE == 0
    }
    /// The actual current, mA RMS (DRV_STATUS.CS_ACTUAL with CHOPCONF.vsense).
    pub fn actual_ma(&self, rsense_ohm: f32) -> f32 {
        let cs = ((self.drv_status >> 16) & 0x1F) as u8;
        current_ma(self.chopconf & (1 << 17) != 0, cs, rsense_ohm)
    }
    /// Over-temperature warning (DRV_STATUS.otpw) or shutdown (ot).
    pub fn overtemp(&self) -> (bool, bool) {
        (self.drv_status & 1 != 0, self.drv_status & 2 != 0)
    }
    /// Short to ground or supply on either coil (s2ga, s2gb, s2vsa, s2vsb).
    pub fn short(&self) -> bool {
        self.drv_status & 0b11_1100 != 0
    }
    /// Open load on either coil (ola, olb): a motor not connected (reliable only while moving).
    pub fn open_load(&self) -> bool {
        self.drv_status & 0b1100_0000 != 0
    }
}

/// Bit time at Marlin's `TMC_BAUD_RATE 19200`, ns.
pub const BIT_NS_19200: u32 = 52_083;

/// A bit-banged half-duplex UART (8N1, LSB first) on one pin that is switched between output
/// (sending) and input (receiving), as Marlin's software serial drives the SKR 2's TMC lines.
/// Generic over `embedded-hal` pins and delay; the board supplies a pin whose direction can be
/// switched ([`Direction`]).
pub struct SoftUart<P, D> {
    pin: P,
    delay: D,
    bit_ns: u32,
    /// How long to wait for a reply's start bit, ns.
    timeout_ns: u32,
}

/// A pin that can be switched between driving the line and listening to it.
pub trait Direction {
    /// Drive the line (output, idle high) or release it (input).
    fn set_output(&mut self, output: bool);
}

impl<P: OutputPin + InputPin + Direction, D: DelayNs> SoftUart<P, D> {
    /// A UART at `bit_ns` per bit waiting up to `timeout_ns` for each reply byte.
    pub fn new(mut pin: P, delay: D, bit_ns: u32, timeout_ns: u32) -> Self {
        let _ = pin.set_high();
        pin.set_output(false);
        SoftUart {
            pin,
            delay,
            bit_ns,
            timeout_ns,
        }
    }

    fn send_byte(&mut self, byte: u8) {
        let frame = (u16::from(byte) << 1) | (1 << 9); // start 0, 8 data, stop 1
        for i in 0..10 {
            let _ = if frame & (1 << i) != 0 {
                self.pin.set_high()
            } else {
                self.pin.set_low()
            };
            self.delay.delay_ns(self.bit_ns);
        }
    }

    /// One byte, or None if no start bit came within the timeout or the stop bit is missing.
    fn receive_byte(&mut self) -> Option<u8> {
        let poll_ns = (self.bit_ns / 8).max(1);
        let mut waited = 0u32;
        while self.pin.is_high().unwrap_or(true) {
            if waited >= self.timeout_ns {
                return None;
            }
            self.delay.delay_ns(poll_ns);
            waited = waited.saturating_add(poll_ns);
        }
        // Middle of the first data bit: 1.5 bits after the falling edge.
        self.delay.delay_ns(self.bit_ns + self.bit_ns / 2);
        let mut byte = 0u8;
        for i in 0..8 {
            if self.pin.is_high().unwrap_or(false) {
                byte |= 1 << i;
            }
            self.delay.delay_ns(self.bit_ns);
        }
        // Now in the middle of the stop bit.
        let stop = self.pin.is_high().unwrap_or(false);
        self.delay.delay_ns(self.bit_ns / 2);
        stop.then_some(byte)
    }
}

impl<P: OutputPin + InputPin + Direction, D: DelayNs> SingleWire for SoftUart<P, D> {
    fn send(&mut self, bytes: &[u8]) {
        let _ = self.pin.set_high();
        self.pin.set_output(true);
        self.delay.delay_ns(self.bit_ns);
        for &b in bytes {
            self.send_byte(b);
        }
        self.pin.set_output(false);
    }

    fn receive(&mut self, buf: &mut [u8]) -> usize {
        let mut n = 0;
        for slot in buf.iter_mut() {
            match self.receive_byte() {
                Some(b) => *slot = b,
                None => break,
            }
            n += 1;
        }
        n
    }
}

#[cfg(any(test, feature = "tmc-model"))]
pub mod model;
#[cfg(test)]
mod tests;
