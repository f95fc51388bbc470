//! Checks of the board's portable drivers (`firmware::drivers`, generic over
//! `embedded-hal`), run on the emulated Cortex-M4 and on the host with pins supplied here,
//! plus the cost of driving the pins for one step event.
#![cfg_attr(not(target_os = "none"), allow(dead_code))]

use crate::board_homing;
use core::cell::Cell;
use core::convert::Infallible;
use drivers::homing_watch::{EndstopWatch, EventFlags};
use drivers::{IdleTimeout, PauseButton, StepperPins};
use embedded_hal::digital::{ErrorType, InputPin, OutputPin};
use firmware::drivers;
use firmware::drivers::tmc2209;
use firmware::homing::{Endstops, PinEndstops};
use firmware::motion::Axis;
use firmware::motion::{PauseMode, Realtime};

/// An output that records its level in a shared bit field.
pub struct LevelPin<'a> {
    levels: &'a Cell<u32>,
    bit: u32,
}

impl ErrorType for LevelPin<'_> {
    type Error = Infallible;
}

impl OutputPin for LevelPin<'_> {
    fn set_low(&mut self) -> Result<(), Infallible> {
        self.levels.set(self.levels.get() & !(1 << self.bit));
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        self.levels.set(self.levels.get() | (1 << self.bit));
        Ok(())
    }
}

/// An input reading a shared flag.
pub struct FlagInput<'a> {
    flag: &'a Cell<bool>,
}

impl ErrorType for FlagInput<'_> {
    type Error = Infallible;
}

impl InputPin for FlagInput<'_> {
    fn is_high(&mut self) -> Result<bool, Infallible> {
        Ok(self.flag.get())
    }
    fn is_low(&mut self) -> Result<bool, Infallible> {
        Ok(!self.flag.get())
    }
}

/// An output that writes a GPIO BSRR-style register (volatile store), as on the STM32: what a
/// step costs on the real pins.
pub struct RegPin {
    reg: *mut u32,
    bit: u32,
}

impl ErrorType for RegPin {
    type Error = Infallible;
}

impl OutputPin for RegPin {
    fn set_low(&mut self) -> Result<(), Infallible> {
        // SAFETY: `reg` points at a live static for the whole run.
        unsafe { core::ptr::write_volatile(self.reg, 1 << (self.bit + 16)) };
        Ok(())
    }
    fn set_high(&mut self) -> Result<(), Infallible> {
        // SAFETY: as above.
        unsafe { core::ptr::write_volatile(self.reg, 1 << self.bit) };
        Ok(())
    }
}

/// A failed check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CheckFailed(pub &'static str);

fn check(ok: bool, what: &'static str) -> Result<(), CheckFailed> {
    if ok {
        Ok(())
    } else {
        Err(CheckFailed(what))
    }
}

fn steppers(levels: &Cell<u32>) -> StepperPins<LevelPin<'_>> {
    let pin = |bit| LevelPin { levels, bit };
    // Bits 0..3 STEP, 4..7 DIR, 8..11 EN.
    StepperPins::new(
        [pin(0), pin(1), pin(2), pin(3)],
        [pin(4), pin(5), pin(6), pin(7)],
        [pin(8), pin(9), pin(10), pin(11)],
        0b0111, // E wired inverted
    )
}

/// Runs every check.
#[inline(never)]
pub fn run() -> Result<u32, CheckFailed> {
    let mut n = 0;
    // Stepper pins: enable is active low, DIR follows the wiring, STEP is a pulse.
    let levels = Cell::new(0);
    let mut s = steppers(&levels);
    check(levels.get() & 0xF00 == 0xF00, "drivers start disabled")?;
    s.set_enabled(true);
    check(levels.get() & 0xF00 == 0, "enable drives EN low")?;
    // M18 X E: only those drivers go off; M17 X brings X back.
    s.set_axes_enabled(0b1001, false);
    check(
        levels.get() & 0xF00 == 0x900 && s.enabled_mask() == 0b0110,
        "M18 X E disables X and E only",
    )?;
    s.set_axes_enabled(0b0001, true);
    check(
        levels.get() & 0xF00 == 0x800 && s.enabled_mask() == 0b0111,
        "M17 X enables X",
    )?;
    s.set_enabled(true);
    check(levels.get() & 0xF00 == 0, "enable all")?;
    check(
        s.set_dirs(0b1001, 0b1001),
        "first direction change reported",
    )?;
    check(levels.get() & 0x10 != 0, "X positive = DIR high")?;
    check(levels.get() & 0x80 == 0, "E positive = DIR low (inverted)")?;
    check(
        !s.set_dirs(0b1001, 0b1001),
        "same direction: no setup delay needed",
    )?;
    check(s.set_dirs(0b0001, 0b0000), "X reversal reported")?;
    s.step_high(0b0101);
    check(
        levels.get() & 0xF == 0b0101,
        "STEP high on stepping axes only",
    )?;
    s.step_low();
    check(levels.get() & 0xF == 0, "STEP low after the pulse")?;
    n += 1;

    // Endstops: polarity per axis.
    let flag = Cell::new(true);
    let mut e = PinEndstops {
        x: FlagInput { flag: &flag },
        y: FlagInput { flag: &flag },
        z: FlagInput { flag: &flag },
        pressed_high: 0b011,
    };
    check(
        e.triggered(Axis::X) && !e.triggered(Axis::Z),
        "endstop polarity",
    )?;
    check(!e.triggered(Axis::E), "E has no endstop")?;
    n += 1;

    // Pause button: bounces are ignored, a short press pauses at the layer, a long press
    // pauses now (while held), a press while paused resumes.
    let mut b = PauseButton::new();
    let mut got = None;
    let mut t = 0u64;
    for i in 0..10 {
        // 10 ms of contact bounce, 1 ms per reading.
        if let Some(r) = b.update(i % 2 == 0, t, false) {
            got = Some(r);
        }
        t += 1_000;
    }
    for _ in 0..200 {
        if let Some(r) = b.update(true, t, false) {
            got = Some(r);
        }
        t += 1_000;
    }
    check(got.is_none(), "nothing raised while pressed briefly")?;
    for _ in 0..50 {
        if let Some(r) = b.update(false, t, false) {
            check(got.is_none(), "one request per press")?;
            got = Some(r);
        }
        t += 1_000;
    }
    check(
        got == Some(Realtime::Pause(PauseMode::Layer)),
        "short press = pause at layer",
    )?;
    let mut got = None;
    let mut when = 0;
    for _ in 0..3000 {
        if let Some(r) = b.update(true, t, false) {
            check(got.is_none(), "one request per long press")?;
            got = Some(r);
            when = t;
        }
        t += 1_000;
    }
    check(
        got == Some(Realtime::Pause(PauseMode::Now)),
        "long press = pause now",
    )?;
    for _ in 0..50 {
        check(
            b.update(false, t, true).is_none(),
            "release after long press raises nothing",
        )?;
        t += 1_000;
    }
    let _ = when;
    let mut got = None;
    for _ in 0..50 {
        if let Some(r) = b.update(true, t, true) {
            got = Some(r);
        }
        t += 1_000;
    }
    check(got == Some(Realtime::Resume), "press while paused = resume")?;
    n += 1;

    // Idle timeout.
    let mut idle = IdleTimeout::new(120);
    check(!idle.update(true, 0), "busy never times out")?;
    check(!idle.update(false, 119_000_000), "not before 120 s")?;
    check(idle.update(false, 120_000_000), "off after 120 s idle")?;
    n += 1;

    // G28 through the planner with the board's step interrupt model (board_homing.rs).
    n += board_homing::run().map_err(|board_homing::Failed(what)| CheckFailed(what))?;
    n += tmc()?;
    Ok(n)
}

/// A register-level TMC2209 on a single wire, without allocation: keeps the registers, counts
/// valid writes in IFCNT, answers reads addressed to it (or stays silent, or flips a bit).
struct TmcModel {
    regs: [u32; 128],
    ifcnt: u8,
    reply: [u8; 8],
    reply_len: usize,
    silent: bool,
    corrupt: bool,
}

impl TmcModel {
    fn new(silent: bool, corrupt: bool) -> Self {
        let mut regs = [0; 128];
        regs[0x06] = 0x21 << 24;
        TmcModel {
            regs,
            ifcnt: 0,
            reply: [0; 8],
            reply_len: 0,
            silent,
            corrupt,
        }
    }
}

impl tmc2209::SingleWire for TmcModel {
    fn send(&mut self, bytes: &[u8]) {
        self.reply_len = 0;
        let Some((&crc, body)) = bytes.split_last() else {
            return;
        };
        if tmc2209::crc8(body) != crc || body.first() != Some(&0x05) || body.get(1) != Some(&0) {
            return;
        }
        match *body {
            [_, _, r, a, b, c, d] if r & 0x80 != 0 => {
                let v = u32::from_be_bytes([a, b, c, d]);
                match r & 0x7F {
                    0x01 => self.regs[1] &= !v,
                    0x02 | 0x06 | 0x6F => {}
                    x => self.regs[usize::from(x)] = v,
                }
                self.ifcnt = self.ifcnt.wrapping_add(1);
            }
            [_, _, r] if !self.silent => {
                let v = if r == 0x02 {
                    u32::from(self.ifcnt)
                } else {
                    self.regs[usize::from(r & 0x7F)]
                };
                let d = v.to_be_bytes();
                self.reply = [0x05, 0xFF, r, d[0], d[1], d[2], d[3], 0];
                self.reply[7] = tmc2209::crc8(&self.reply[..7]);
                if self.corrupt {
                    self.reply[4] ^= 0x04;
                }
                self.reply_len = 8;
            }
            _ => {}
        }
    }

    fn receive(&mut self, buf: &mut [u8]) -> usize {
        let n = self.reply_len.min(buf.len());
        buf[..n].copy_from_slice(&self.reply[..n]);
        self.reply_len = 0;
        n
    }
}

/// The TMC2209 datagrams and register logic on the emulated core: fixed datagrams (bytes the
/// host tests check against the `tmc2209` crate), a healthy driver configured and read back, a
/// silent one and a corrupted reply refused.
fn tmc() -> Result<u32, CheckFailed> {
    use firmware::drivers::tmc2209::{
        read_request, reg, write_datagram, DriverSettings, Tmc2209, TmcError,
    };
    check(
        write_datagram(0, reg::GCONF, 0x1C0) == [0x05, 0x00, 0x80, 0x00, 0x00, 0x01, 0xC0, 0xF6],
        "TMC2209 write datagram",
    )?;
    check(
        read_request(0, reg::IFCNT) == [0x05, 0x00, 0x02, 0x8F],
        "TMC2209 read request",
    )?;
    let s = DriverSettings::ender3(580);
    let mut d = Tmc2209::new(TmcModel::new(false, false), 0);
    check(d.configure(&s) == Ok(()), "TMC2209 configured")?;
    let m = d.wire_mut();
    check(
        m.regs[0x00] == 0x1C0 && m.regs[0x6C] == 0x1402_8104 && m.regs[0x10] == 0x000A_1108,
        "TMC2209 GCONF, CHOPCONF, IHOLD_IRUN for 580 mA at 1/16",
    )?;
    check(m.ifcnt == 6, "TMC2209 every write counted")?;
    let mut d = Tmc2209::new(TmcModel::new(true, false), 0);
    check(
        d.configure(&s) == Err(TmcError::NoReply(0)),
        "TMC2209 silent driver reported",
    )?;
    let mut d = Tmc2209::new(TmcModel::new(false, true), 0);
    check(
        d.configure(&s) == Err(TmcError::BadCrc),
        "TMC2209 corrupted reply refused",
    )?;
    Ok(1)
}

/// Fake BSRR register for [`isr_cost`].
static mut BSRR: u32 = 0;

#[derive(Clone, Copy)]
struct Ev {
    t_ticks: u64,
    axis_mask: u8,
    dir_mask: u8,
    flags: EventFlags,
}

/// The step interrupt's work per event without the busy-wait delays: the queue pop (as in
/// `board::stepper`), the re-timer's due time and its bookkeeping (`drivers::retime`, with the
/// board's limits: 4 MHz ticks, the Ender-3 floors, 2 µs minimum step period, 20 µs
/// tolerance, 20 ms rest gap), the due-time comparison, and `StepExecutor::fire` (limits, DIR,
/// STEP high/low, position) on register-writing pins. Events are queued in batches of 200 (not
/// timed: that is the motion loop's side); `mark(true/false)` brackets each consuming batch.
pub fn isr_cost(events: u32, mut mark: impl FnMut(bool)) -> u32 {
    let reg = core::ptr::addr_of_mut!(BSRR);
    let pin = |bit| RegPin { reg, bit };
    let pins = StepperPins::new(
        [pin(0), pin(1), pin(2), pin(3)],
        [pin(4), pin(5), pin(6), pin(7)],
        [pin(8), pin(9), pin(10), pin(11)],
        0b1111,
    );
    let mut exec = drivers::StepExecutor::new(pins);
    exec.homed = 0b111;
    exec.pins.set_enabled(true);
    let mut watch = EndstopWatch::new();
    let open = Cell::new(false);
    let mut endstops = PinEndstops {
        x: FlagInput { flag: &open },
        y: FlagInput { flag: &open },
        z: FlagInput { flag: &open },
        pressed_high: 0b111,
    };
    let cfg = firmware::config::MachineConfig::ENDER3;
    let mut floors = [8u32; 4];
    for (axis, f) in firmware::motion::Axis::ALL
        .into_iter()
        .zip(floors.iter_mut())
    {
        let a = cfg.axis(axis);
        *f = drivers::retime::axis_floor_ticks(a.steps_per_mm, a.max_feed_mm_s, 4_000_000, 8);
    }
    let mut retime = drivers::retime::Retimer::new(drivers::retime::RetimeConfig {
        min_period_ticks: floors,
        min_step_ticks: 8,
        latency_slack_ticks: 2,
        late_tolerance_ticks: 80,
        rest_gap_ticks: 80_000,
    });
    let mut queue: heapless::spsc::Queue<Ev, 256> = heapless::spsc::Queue::new();
    let (mut producer, mut consumer) = queue.split();
    let mut stepped = 0u32;
    let mut i = 0u32;
    while i < events {
        for _ in 0..200 {
            let dir = if (i / 64) % 2 == 0 { 0b0011 } else { 0b0000 };
            let _ = producer.enqueue(Ev {
                t_ticks: u64::from(i),
                axis_mask: 0b0011 | (((i & 1) as u8) << 3),
                dir_mask: dir,
                flags: EventFlags(0),
            });
            i += 1;
        }
        mark(true);
        let now = core::hint::black_box(u64::MAX - 1);
        while let Some(ev) = consumer.peek().copied() {
            let due = retime.due(ev.t_ticks, ev.axis_mask);
            if due > now + 1 {
                break;
            }
            let _ = consumer.dequeue();
            if !watch.admit(ev.flags, ev.axis_mask, ev.dir_mask, &mut endstops) {
                continue;
            }
            let m = if ev.flags.homing() {
                exec.fire_homing(ev.axis_mask, ev.dir_mask, 650, 1000, |_| {})
            } else {
                exec.fire(ev.axis_mask, ev.dir_mask, 650, 1000, |_| {})
            };
            retime.fired(m, now);
            stepped += u32::from(m != 0);
        }
        mark(false);
    }
    stepped
}
