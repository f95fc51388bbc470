//! The TMC2209 datagram and register logic against a register-level model of the driver
//! ([`super::model`], also what the emulated board's drivers answer with). The model checks
//! CRCs with the `tmc2209` crate's own implementation (not this module's), and the register
//! layouts are compared with that crate's bitfields.

use super::model::{Behaviour, Model};
use super::*;

fn driver(behaviour: Behaviour) -> Tmc2209<Model> {
    Tmc2209::new(Model::new(0, behaviour), 0)
}

#[test]
fn datagrams_match_the_tmc2209_crate() {
    for r in [0x00u8, 0x02, 0x06, 0x6C, 0x6F] {
        for addr in 0..4 {
            let g = read_request(addr, r);
            assert_eq!(g[3], tmc2209::crc(&g[..3]));
        }
    }
    for (r, addr, v) in [
        (tmc2209::reg::Address::GCONF, 0u8, 0x1C0u32),
        (tmc2209::reg::Address::CHOPCONF, 3, 0x1401_0104),
        (tmc2209::reg::Address::IHOLD_IRUN, 1, 0x000A_1008),
        (tmc2209::reg::Address::TPWMTHRS, 2, 0xFFFFF),
    ] {
        let theirs = tmc2209::WriteRequest::from_raw_data(addr, r, v);
        assert_eq!(&write_datagram(addr, r as u8, v)[..], theirs.bytes());
    }
}

#[test]
fn register_values_match_the_crates_bitfields() {
    let s = DriverSettings::ender3(800);
    let regs = s.registers();
    let mut g = tmc2209::reg::GCONF(0);
    g.set_pdn_disable(true);
    g.set_mstep_reg_select(true);
    g.set_multistep_filt(true);
    g.set_i_scale_analog(false);
    g.set_en_spread_cycle(false);
    assert_eq!(regs[0], (reg::GCONF, g.0));

    let (vsense, cs) = tmc2209::rms_current_to_vsense_cs(0.11, 800.0);
    assert_eq!(current_scale(800, 0.11), (vsense, cs));
    let mut c = tmc2209::reg::CHOPCONF(0);
    c.set_toff(4);
    c.set_hend(2);
    c.set_hstrt(0);
    c.set_tbl(1);
    c.set_intpol(true);
    c.set_vsense(vsense);
    c.set_mres(tmc2209::data::MicroStepResolution::from_microsteps(16));
    assert_eq!(regs[1], (reg::CHOPCONF, c.0));

    let mut i = tmc2209::reg::IHOLD_IRUN(0);
    i.set_irun(cs);
    // Half the current: round((cs + 1) / 2) − 1.
    i.set_ihold(((f32::from(cs) + 1.0) / 2.0).round() as u8 - 1);
    i.set_ihold_delay(10);
    assert_eq!(regs[2], (reg::IHOLD_IRUN, i.0));

    let mut spread = s;
    spread.stealthchop = false;
    assert_ne!(spread.registers()[0].1 & gconf::EN_SPREADCYCLE, 0);
}

#[test]
fn current_round_trips_within_one_step() {
    for ma in [300u16, 580, 650, 800, 1000, 1200, 1700] {
        let (vsense, cs) = current_scale(ma, RSENSE_OHM);
        let back = current_ma(vsense, cs, RSENSE_OHM);
        let step = current_ma(vsense, cs.saturating_add(1).min(31), RSENSE_OHM) - back;
        assert!(back <= f32::from(ma) + 1.0, "{ma}: {back}");
        assert!(f32::from(ma) - back <= step + 1.0, "{ma}: {back} (+{step})");
    }
    // 0.11 Ω: the most a TMC2209 module gives is about 1.77 A RMS; more clamps to CS 31.
    assert_eq!(current_scale(5000, RSENSE_OHM), (false, 31));
}

#[test]
fn microsteps_and_mres() {
    for (m, r) in [(256u16, 0u8), (128, 1), (32, 3), (16, 4), (8, 5), (1, 8)] {
        assert_eq!(mres(m), r);
        assert_eq!(microsteps_of(r), m);
    }
}

#[test]
fn tpwmthrs_like_marlin() {
    // Marlin's _tmc_thrs(16, 100 mm/s, 80 steps/mm) = 12 MHz · 16 / (256 · 100 · 80) = 93.
    assert_eq!(tpwmthrs(100.0, 80.0, 16), 93);
    assert_eq!(tpwmthrs(0.0, 80.0, 16), 0);
    assert_eq!(tpwmthrs(f32::NAN, 80.0, 16), 0);
}

#[test]
fn configure_a_healthy_driver() {
    let mut d = driver(Behaviour::Answers);
    let s = DriverSettings::ender3(800);
    assert_eq!(d.configure(&s), Ok(()));
    let m = d.wire_mut();
    for (r, v) in s.registers() {
        assert_eq!(m.regs[usize::from(r)], v, "register 0x{r:02X}");
    }
    assert_eq!(m.regs[1], 0, "GSTAT cleared");
    // Five settings and the GSTAT clear, each counted.
    assert_eq!(m.ifcnt, 6);
    let rep = d.report().unwrap();
    assert_eq!(rep.microsteps(), 16);
    assert!(rep.stealthchop());
    let ma = rep.actual_ma(RSENSE_OHM);
    assert!((ma - 800.0).abs() < 60.0, "{ma}");
    assert!(!rep.short() && !rep.open_load());
}

#[test]
fn a_silent_driver_is_reported() {
    let mut d = driver(Behaviour::Silent);
    assert_eq!(
        d.configure(&DriverSettings::ender3(800)),
        Err(TmcError::NoReply(0))
    );
    // Nothing was written before the version check failed.
    assert_eq!(d.wire_mut().seen.len(), 1);
}

#[test]
fn a_corrupted_reply_is_refused() {
    let mut d = driver(Behaviour::CorruptsReplies);
    assert_eq!(d.read(reg::GCONF), Err(TmcError::BadCrc));
    assert_eq!(
        d.configure(&DriverSettings::ender3(800)),
        Err(TmcError::BadCrc)
    );
}

#[test]
fn a_cut_reply_is_refused() {
    let mut d = driver(Behaviour::CutsReplies(5));
    assert_eq!(d.read(reg::IOIN), Err(TmcError::NoReply(5)));
}

#[test]
fn dropped_writes_are_caught_by_ifcnt() {
    let mut d = driver(Behaviour::DropsWrites);
    assert_eq!(
        d.configure(&DriverSettings::ender3(800)),
        Err(TmcError::WriteNotCounted)
    );
}

#[test]
fn only_the_addressed_driver_answers() {
    // Model at address 1, firmware talking to address 0: silence.
    let mut d = Tmc2209::new(Model::new(1, Behaviour::Answers), 0);
    assert_eq!(d.read(reg::IOIN), Err(TmcError::NoReply(0)));
    let mut d = Tmc2209::new(Model::new(1, Behaviour::Answers), 1);
    assert_eq!(d.read(reg::IOIN).map(|v| v >> 24), Ok(0x21));
}

#[test]
fn reply_from_another_register_is_refused() {
    let mut g = [0x05, 0xFF, 0x6C, 0, 0, 0, 0, 0];
    g[7] = tmc2209::crc(&g[..7]);
    assert_eq!(parse_reply(&g, reg::GCONF), Err(TmcError::BadReply));
    assert_eq!(parse_reply(&g, reg::CHOPCONF), Ok(0));
}

/// A line in virtual time: the UART drives it while output; while input, it reads a waveform
/// the test scripted (a driver's reply).
mod line {
    use super::*;
    use core::cell::RefCell;
    use std::rc::Rc;

    #[derive(Default)]
    pub struct Line {
        pub t_ns: u64,
        pub output: bool,
        /// (time, level) edges the UART drove.
        pub driven: Vec<(u64, bool)>,
        /// (time, level) edges of the scripted reply; high before the first.
        pub script: Vec<(u64, bool)>,
    }

    #[derive(Clone)]
    pub struct Pin(pub Rc<RefCell<Line>>);
    #[derive(Clone)]
    pub struct Clock(pub Rc<RefCell<Line>>);

    impl embedded_hal::digital::ErrorType for Pin {
        type Error = core::convert::Infallible;
    }
    impl OutputPin for Pin {
        fn set_low(&mut self) -> Result<(), Self::Error> {
            let mut l = self.0.borrow_mut();
            let t = l.t_ns;
            if l.output {
                l.driven.push((t, false));
            }
            Ok(())
        }
        fn set_high(&mut self) -> Result<(), Self::Error> {
            let mut l = self.0.borrow_mut();
            let t = l.t_ns;
            if l.output {
                l.driven.push((t, true));
            }
            Ok(())
        }
    }
    impl InputPin for Pin {
        fn is_high(&mut self) -> Result<bool, Self::Error> {
            let l = self.0.borrow();
            Ok(l.script
                .iter()
                .take_while(|(t, _)| *t <= l.t_ns)
                .last()
                .is_none_or(|(_, v)| *v))
        }
        fn is_low(&mut self) -> Result<bool, Self::Error> {
            self.is_high().map(|h| !h)
        }
    }
    impl Direction for Pin {
        fn set_output(&mut self, output: bool) {
            self.0.borrow_mut().output = output;
        }
    }
    impl DelayNs for Clock {
        fn delay_ns(&mut self, ns: u32) {
            self.0.borrow_mut().t_ns += u64::from(ns);
        }
    }

    /// The waveform of `bytes` sent 8N1 from `t0_ns`.
    pub fn waveform(bytes: &[u8], t0_ns: u64, bit_ns: u64) -> Vec<(u64, bool)> {
        let mut w = Vec::new();
        let mut t = t0_ns;
        for &b in bytes {
            let frame = (u16::from(b) << 1) | (1 << 9);
            for i in 0..10 {
                w.push((t, frame & (1 << i) != 0));
                t += bit_ns;
            }
        }
        w
    }

    /// Decodes what the UART drove, sampling each bit in its middle.
    pub fn decode(driven: &[(u64, bool)], bit_ns: u64) -> Vec<u8> {
        let level = |t: u64| {
            driven
                .iter()
                .take_while(|(te, _)| *te <= t)
                .last()
                .is_none_or(|(_, v)| *v)
        };
        let mut out = Vec::new();
        let end = driven.last().map_or(0, |(t, _)| *t);
        let mut t = 0;
        while t <= end {
            if level(t) {
                t += bit_ns / 16;
                continue;
            }
            let mut b = 0u8;
            for i in 0..8 {
                if level(t + bit_ns * (i + 1) + bit_ns / 2) {
                    b |= 1 << i;
                }
            }
            out.push(b);
            t += bit_ns * 10 - bit_ns / 2;
        }
        out
    }
}

#[test]
fn soft_uart_sends_and_receives_8n1() {
    use core::cell::RefCell;
    use std::rc::Rc;
    let bit = u64::from(BIT_NS_19200);
    let l = Rc::new(RefCell::new(line::Line::default()));
    let mut uart = SoftUart::new(
        line::Pin(l.clone()),
        line::Clock(l.clone()),
        BIT_NS_19200,
        2_000_000,
    );
    let req = read_request(0, reg::IOIN);
    uart.send(&req);
    assert_eq!(line::decode(&l.borrow().driven, bit), req.to_vec());
    assert!(!l.borrow().output, "line released after sending");

    // The driver answers 8 bit times after the request (its SENDDELAY).
    let mut reply = [0x05, 0xFF, reg::IOIN, 0x21, 0, 0x01, 0x40, 0];
    reply[7] = tmc2209::crc(&reply[..7]);
    let t0 = l.borrow().t_ns + 8 * bit;
    l.borrow_mut().script = line::waveform(&reply, t0, bit);
    let mut buf = [0u8; 8];
    assert_eq!(uart.receive(&mut buf), 8);
    assert_eq!(buf, reply);
    assert_eq!(parse_reply(&buf, reg::IOIN).map(|v| v >> 24), Ok(0x21));

    // Silence: nothing within the timeout.
    let before = l.borrow().t_ns;
    assert_eq!(uart.receive(&mut buf), 0);
    let waited = l.borrow().t_ns - before;
    assert!((2_000_000..2_100_000).contains(&waited), "{waited}");
}
