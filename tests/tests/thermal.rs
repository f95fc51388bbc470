//! Heater control and thermal protection on the simulator's heater model: the firmware's
//! `thermal` state machine is fed 12-bit ADC samples from `sim::heater` at 10 Hz, exactly as
//! the board feeds it, and its duty drives the model. Proves that PID holds the target, that
//! M303 finds usable gains, and that runaway, slow heating, sensor faults and a stuck MOSFET
//! are all caught with every heater switched off.

use firmware::thermal::{AutotuneStatus, FaultKind, HeaterId, IdleConfig, Thermal, ThermalConfig};
use sim::heater::{HeaterFault, HeaterModel, HeaterParams};

const SAMPLE_US: u64 = 100_000;

struct Rig {
    thermal: Thermal,
    hotend: HeaterModel,
    bed: HeaterModel,
    now_us: u64,
}

impl Rig {
    fn new(cfg: &ThermalConfig) -> Self {
        Rig {
            thermal: Thermal::new(cfg),
            hotend: HeaterModel::new(HeaterParams::ENDER3_HOTEND),
            bed: HeaterModel::new(HeaterParams::ENDER3_BED),
            now_us: 0,
        }
    }

    /// One 100 ms sample period for both heaters.
    fn tick(&mut self) {
        let dh = self
            .thermal
            .update_adc(HeaterId::Hotend, self.hotend.adc(), self.now_us);
        let db = self
            .thermal
            .update_adc(HeaterId::Bed, self.bed.adc(), self.now_us);
        self.hotend.step(dh, SAMPLE_US as f32 * 1e-6);
        self.bed.step(db, SAMPLE_US as f32 * 1e-6);
        self.now_us += SAMPLE_US;
    }

    fn run_s(&mut self, seconds: f32) {
        let n = (seconds * 1e6 / SAMPLE_US as f32) as u64;
        for _ in 0..n {
            self.tick();
        }
    }

    /// Runs until `cond` or `limit_s`; returns the seconds it took.
    fn run_until(&mut self, limit_s: f32, mut cond: impl FnMut(&Rig) -> bool) -> Option<f32> {
        let start = self.now_us;
        while ((self.now_us - start) as f32) * 1e-6 < limit_s {
            if cond(self) {
                return Some((self.now_us - start) as f32 * 1e-6);
            }
            self.tick();
        }
        None
    }

    fn s(&self) -> f32 {
        self.now_us as f32 * 1e-6
    }
}

fn heat_and_settle(rig: &mut Rig, hotend_c: f32, bed_c: f32) {
    rig.thermal.set_target(HeaterId::Hotend, hotend_c).unwrap();
    rig.thermal.set_target(HeaterId::Bed, bed_c).unwrap();
    let took = rig.run_until(600.0, |r| {
        r.thermal.reached(HeaterId::Hotend) && r.thermal.reached(HeaterId::Bed)
    });
    assert!(
        took.is_some(),
        "targets not reached: hotend {} bed {} fault {:?}",
        rig.thermal.temperature_c(HeaterId::Hotend),
        rig.thermal.temperature_c(HeaterId::Bed),
        rig.thermal.fault()
    );
}

#[test]
fn pid_holds_hotend_and_bed_within_one_degree() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    heat_and_settle(&mut rig, 200.0, 60.0);
    // Settle two more minutes, then watch ten minutes of holding.
    rig.run_s(120.0);
    let (mut worst_h, mut worst_b) = (0.0f32, 0.0f32);
    for _ in 0..6000 {
        rig.tick();
        worst_h = worst_h.max((rig.hotend.temperature_c() - 200.0).abs());
        worst_b = worst_b.max((rig.bed.temperature_c() - 60.0).abs());
    }
    assert!(rig.thermal.fault().is_none());
    assert!(worst_h <= 1.0, "hot end strayed {worst_h} °C");
    assert!(worst_b <= 1.0, "bed strayed {worst_b} °C");
    // Holding 200 °C costs about (200 − 25) · 0.08 / 40 = 35 % duty.
    let duty = rig.thermal.duty(HeaterId::Hotend);
    assert!((0.2..0.5).contains(&duty), "duty {duty}");
}

#[test]
fn heat_up_time_is_realistic_and_m109_waits_for_residency() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    rig.thermal.set_target(HeaterId::Hotend, 200.0).unwrap();
    let reach = rig
        .run_until(300.0, |r| {
            r.thermal.temperature_c(HeaterId::Hotend) >= 199.0
        })
        .unwrap();
    assert!(
        (40.0..150.0).contains(&reach),
        "reached 199 °C after {reach} s"
    );
    assert!(
        !rig.thermal.reached(HeaterId::Hotend),
        "residency not yet served"
    );
    let settle = rig
        .run_until(300.0, |r| r.thermal.reached(HeaterId::Hotend))
        .unwrap();
    assert!(
        settle >= 9.9,
        "M109 released after only {settle} s in the window"
    );
}

#[test]
fn thermistor_falling_out_is_a_runaway() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    heat_and_settle(&mut rig, 200.0, 60.0);
    rig.run_s(30.0);
    let injected = rig.s();
    rig.hotend.set_fault(Some(HeaterFault::SensorDetached));
    rig.run_until(120.0, |r| r.thermal.fault().is_some());
    let fault = rig.thermal.fault().expect("runaway not detected");
    assert_eq!(fault.kind, FaultKind::Runaway);
    assert_eq!(fault.heater, HeaterId::Hotend);
    let after = fault.at_us as f32 * 1e-6 - injected;
    // The sensor needs a few seconds to fall 4 °C, then the 40 s period runs.
    assert!(
        (40.0..55.0).contains(&after),
        "runaway detected {after} s after the fault"
    );
    // Every heater is off, stays off, and new targets are refused.
    rig.run_s(5.0);
    assert_eq!(rig.thermal.duty(HeaterId::Hotend), 0.0);
    assert_eq!(rig.thermal.duty(HeaterId::Bed), 0.0);
    assert!(rig.thermal.set_target(HeaterId::Bed, 60.0).is_err());
    assert_eq!(
        fault.to_string(),
        "Thermal Runaway, system stopped! Heater_ID: 0"
    );
}

#[test]
fn bed_runaway_is_caught_too() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    heat_and_settle(&mut rig, 0.0, 60.0);
    rig.bed.set_fault(Some(HeaterFault::SensorDetached));
    rig.run_until(200.0, |r| r.thermal.fault().is_some());
    let fault = rig.thermal.fault().expect("bed runaway not detected");
    assert_eq!(
        (fault.heater, fault.kind),
        (HeaterId::Bed, FaultKind::Runaway)
    );
}

#[test]
fn dead_heater_is_heating_failed() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    rig.hotend.set_fault(Some(HeaterFault::HeaterDead));
    rig.thermal.set_target(HeaterId::Hotend, 200.0).unwrap();
    rig.run_until(60.0, |r| r.thermal.fault().is_some());
    let fault = rig.thermal.fault().expect("dead heater not detected");
    assert_eq!(fault.kind, FaultKind::HeatingFailed);
    let at = fault.at_us as f32 * 1e-6;
    assert!((19.9..21.0).contains(&at), "detected at {at} s");
}

#[test]
fn weak_heater_is_heating_failed_but_a_normal_one_is_not() {
    // A heater at a twentieth of its power still warms, but by less than 2 °C per 20 s.
    let mut weak = HeaterParams::ENDER3_HOTEND;
    weak.power_w = 2.0;
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    rig.hotend = HeaterModel::new(weak);
    rig.thermal.set_target(HeaterId::Hotend, 200.0).unwrap();
    rig.run_until(120.0, |r| r.thermal.fault().is_some());
    assert_eq!(
        rig.thermal.fault().map(|f| f.kind),
        Some(FaultKind::HeatingFailed)
    );

    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    rig.thermal.set_target(HeaterId::Bed, 60.0).unwrap();
    rig.run_s(600.0);
    assert!(rig.thermal.fault().is_none());
}

#[test]
fn sensor_open_and_short_are_caught_within_half_a_second() {
    for (fault_in, expected) in [
        (HeaterFault::SensorOpen, FaultKind::SensorOpen),
        (HeaterFault::SensorShort, FaultKind::SensorShort),
    ] {
        let mut rig = Rig::new(&ThermalConfig::ENDER3);
        heat_and_settle(&mut rig, 200.0, 0.0);
        let injected = rig.now_us;
        rig.hotend.set_fault(Some(fault_in));
        rig.run_until(5.0, |r| r.thermal.fault().is_some());
        let fault = rig.thermal.fault().expect("sensor fault not detected");
        assert_eq!(fault.kind, expected);
        assert!(fault.at_us - injected <= 500_000);
        assert_eq!(rig.thermal.duty(HeaterId::Hotend), 0.0);
    }
}

#[test]
fn degree_samples_with_fault_markers() {
    // The executive's path: °C samples, faults as ±∞ markers from the table.
    let table =
        firmware::thermal::ThermistorTable::new(&firmware::thermal::Thermistor::NTC_100K_3950);
    for (raw, kind) in [
        (0u16, FaultKind::SensorShort),
        (4095, FaultKind::SensorOpen),
    ] {
        let mut t = Thermal::new(&ThermalConfig::ENDER3);
        t.set_target(HeaterId::Hotend, 200.0).unwrap();
        let mut now = 0;
        for _ in 0..5 {
            t.update(HeaterId::Hotend, table.celsius_marked(raw), now);
            now += SAMPLE_US;
        }
        assert_eq!(t.fault().map(|f| f.kind), Some(kind));
    }
}

#[test]
fn idle_open_sensor_is_harmless_until_heated() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    rig.bed.set_fault(Some(HeaterFault::SensorOpen));
    rig.run_s(5.0);
    assert!(
        rig.thermal.fault().is_none(),
        "unplugged idle bed is not a fault"
    );
    rig.thermal.set_target(HeaterId::Bed, 60.0).unwrap();
    rig.run_s(1.0);
    assert_eq!(
        rig.thermal.fault().map(|f| f.kind),
        Some(FaultKind::SensorOpen)
    );
}

#[test]
fn stuck_mosfet_ends_in_maxtemp() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    rig.hotend.set_fault(Some(HeaterFault::MosfetStuckOn));
    rig.run_until(600.0, |r| r.thermal.fault().is_some());
    let fault = rig.thermal.fault().expect("overheat not detected");
    assert_eq!(fault.kind, FaultKind::MaxTemp);
    assert!(rig.hotend.temperature_c() < 290.0);
}

#[test]
fn autotune_finds_gains_that_hold_the_target() {
    let mut cfg = ThermalConfig::ENDER3;
    // Start from poor gains so the tuned ones have to do the work.
    cfg.hotend.control = firmware::thermal::Control::Pid(firmware::thermal::PidGains {
        kp: 1.0,
        ki: 0.0,
        kd: 0.0,
    });
    let mut rig = Rig::new(&cfg);
    let now = rig.now_us;
    rig.thermal
        .start_autotune(HeaterId::Hotend, 200.0, 5, true, now)
        .unwrap();
    rig.run_until(1800.0, |r| {
        !matches!(
            r.thermal.autotune_status(HeaterId::Hotend),
            Some(AutotuneStatus::Running { .. })
        )
    });
    let gains = match rig.thermal.autotune_status(HeaterId::Hotend) {
        Some(AutotuneStatus::Done(g)) => g,
        other => panic!(
            "autotune did not finish: {other:?}, fault {:?}",
            rig.thermal.fault()
        ),
    };
    assert!(
        gains.kp > 5.0 && gains.ki > 0.1 && gains.kd > 10.0,
        "{gains:?}"
    );
    assert_eq!(rig.thermal.pid(HeaterId::Hotend), Some(gains), "U1 applies");
    assert_eq!(
        rig.thermal.target_c(HeaterId::Hotend),
        0.0,
        "heater off after a tune"
    );

    heat_and_settle(&mut rig, 200.0, 0.0);
    rig.run_s(120.0);
    let mut worst = 0.0f32;
    for _ in 0..3000 {
        rig.tick();
        worst = worst.max((rig.hotend.temperature_c() - 200.0).abs());
    }
    assert!(worst <= 1.0, "tuned gains strayed {worst} °C ({gains:?})");
}

#[test]
fn bang_bang_bed_holds_its_band() {
    let mut cfg = ThermalConfig::ENDER3;
    cfg.bed.control = firmware::thermal::Control::BangBang { hysteresis_c: 1.0 };
    let mut rig = Rig::new(&cfg);
    heat_and_settle(&mut rig, 0.0, 60.0);
    let mut worst = 0.0f32;
    for _ in 0..3000 {
        rig.tick();
        worst = worst.max((rig.bed.temperature_c() - 60.0).abs());
    }
    assert!(rig.thermal.fault().is_none());
    assert!(worst <= 2.5, "bang-bang bed strayed {worst} °C");
}

#[test]
fn pause_idle_timeout_lowers_and_restores_the_nozzle() {
    let mut cfg = ThermalConfig::ENDER3;
    cfg.idle = Some(IdleConfig {
        timeout_s: 60,
        nozzle_c: 150.0,
    });
    let mut rig = Rig::new(&cfg);
    heat_and_settle(&mut rig, 210.0, 60.0);
    let now = rig.now_us;
    rig.thermal.pause_idle_start(now);
    rig.run_s(59.0);
    assert_eq!(rig.thermal.target_c(HeaterId::Hotend), 210.0);
    rig.run_s(2.0);
    assert_eq!(rig.thermal.target_c(HeaterId::Hotend), 150.0);
    rig.run_s(120.0);
    assert!(rig.hotend.temperature_c() < 160.0);
    assert!(
        rig.thermal.fault().is_none(),
        "cooling to the idle target is no runaway"
    );
    assert_eq!(rig.thermal.pause_idle_end(), Some(210.0));
    assert!(!rig.thermal.reached(HeaterId::Hotend));
    rig.run_until(300.0, |r| r.thermal.reached(HeaterId::Hotend))
        .expect("reheats after resume");
    assert!(rig.thermal.fault().is_none());
}

#[test]
fn m105_report_and_fan() {
    let mut rig = Rig::new(&ThermalConfig::ENDER3);
    rig.thermal.set_target(HeaterId::Hotend, 200.0).unwrap();
    rig.run_s(1.0);
    let mut line = String::new();
    rig.thermal.write_report(&mut line).unwrap();
    assert!(line.starts_with("T:2"), "{line}");
    assert!(line.contains("/200.0 B:"), "{line}");
    assert!(line.ends_with("@:255 B@:0"), "{line}");
    assert!(!rig.thermal.hotend_fan_on());
    rig.run_until(120.0, |r| r.thermal.temperature_c(HeaterId::Hotend) > 51.0);
    assert!(rig.thermal.hotend_fan_on());
}

#[test]
fn bad_targets_are_refused() {
    let mut t = Thermal::new(&ThermalConfig::ENDER3);
    assert!(t.set_target(HeaterId::Hotend, f32::NAN).is_err());
    assert!(t.set_target(HeaterId::Hotend, -5.0).is_err());
    assert!(t.set_target(HeaterId::Hotend, 1e30).is_err());
    assert!(t.set_target(HeaterId::Bed, 115.0).is_err());
    assert!(t.set_target(HeaterId::Bed, 110.0).is_ok());
    assert_eq!(t.target_c(HeaterId::Hotend), 0.0);
}

mod properties {
    use firmware::thermal::{HeaterId, Thermal, ThermalConfig};
    use proptest::prelude::*;

    fn sample() -> impl Strategy<Value = f32> {
        prop_oneof![
            -50.0f32..400.0,
            Just(f32::NAN),
            Just(f32::INFINITY),
            Just(f32::NEG_INFINITY),
            any::<f32>(),
        ]
    }

    proptest! {
        /// Whatever the samples, targets and timing: duty stays within 0..=1, a fault never
        /// clears, and after a fault every duty is 0.
        #[test]
        fn duty_bounded_and_fault_latched(
            steps in proptest::collection::vec(
                (any::<bool>(), sample(), 0u64..2_000_000, proptest::option::of(-10.0f32..300.0)),
                1..300,
            )
        ) {
            let mut t = Thermal::new(&ThermalConfig::ENDER3);
            let mut now = 0u64;
            let mut faulted = false;
            for (bed, c, dt, target) in steps {
                let id = if bed { HeaterId::Bed } else { HeaterId::Hotend };
                if let Some(target) = target {
                    let r = t.set_target(id, target);
                    if faulted {
                        prop_assert!(r.is_err());
                    }
                }
                now += dt;
                let duty = t.update(id, c, now);
                prop_assert!((0.0..=1.0).contains(&duty), "duty {duty}");
                if faulted {
                    prop_assert_eq!(duty, 0.0);
                    prop_assert!(t.fault().is_some());
                }
                faulted = t.fault().is_some();
            }
        }

        /// Every ADC reading converts to a finite temperature or a sensor fault.
        #[test]
        fn any_adc_reading_is_handled(raw in any::<u16>()) {
            let table = firmware::thermal::ThermistorTable::new(
                &firmware::thermal::Thermistor::NTC_100K_3950,
            );
            match table.celsius(raw) {
                Ok(c) => prop_assert!(c.is_finite()),
                Err(_) => prop_assert!(raw <= 20 || raw >= 4075),
            }
        }
    }
}

/// M303 through the executive, as a host sends it (the guide in docs/board.md): the tune runs
/// on the heater model fed at 10 Hz as the board does, and its end is reported as Marlin does
/// (`PID Autotune finished! …`, then `#define DEFAULT_Kp …` lines); `U1` applies the gains.
#[test]
fn m303_on_the_link_reports_and_applies_the_gains() {
    use firmware::config::MachineConfig;
    use firmware::printer::Printer;
    let mut p = Printer::new(MachineConfig::ENDER3);
    let mut hotend = HeaterModel::new(HeaterParams::ENDER3_HOTEND);
    let before = p.thermal().pid(HeaterId::Hotend);
    assert_eq!(p.receive(b"M303 E0 S200 C5 U1\n", 0), 19);
    let mut out = String::new();
    let mut now = 0u64;
    while now < 1_800_000_000 && !out.contains("PID Autotune") {
        p.poll(now);
        let d = p.heater_sample(HeaterId::Hotend, hotend.temperature_c(), now);
        hotend.step(d, SAMPLE_US as f32 * 1e-6);
        let _ = p.write_output(&mut out);
        now += SAMPLE_US;
    }
    let lines: Vec<&str> = out.lines().collect();
    let at = lines
        .iter()
        .position(|l| l.starts_with("PID Autotune finished!"))
        .unwrap_or_else(|| panic!("no result after {} s: {out}", now / 1_000_000));
    let gains = p.thermal().pid(HeaterId::Hotend).expect("PID heater");
    assert_ne!(Some(gains), before, "U1 applies the result");
    assert_eq!(
        lines[at + 1..at + 4],
        [
            format!("#define DEFAULT_Kp {:.2}", gains.kp),
            format!("#define DEFAULT_Ki {:.2}", gains.ki),
            format!("#define DEFAULT_Kd {:.2}", gains.kd),
        ],
        "{out}"
    );
    assert_eq!(
        p.thermal().target_c(HeaterId::Hotend),
        0.0,
        "heater off after"
    );
}
