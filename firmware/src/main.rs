//! The BigTreeTech SKR 2 (STM32F407VG) image: embassy tasks around the portable executive
//! (`firmware::printer::Printer`).
//!
//! * `motion` (every 1 ms): `Printer::poll`, step events into the step interrupt's queue
//!   (`board::stepper`, TIM5 compare at the highest priority), the endstops for G28 (homing
//!   runs through the planner: `firmware::homing`) and M119, the pause button, the stepper
//!   idle timeout, halt handling, host-link output to both ports;
//! * `heaters` (every 1 ms): 10 Hz software PWM of the heaters; every 100 ms the thermistors
//!   are sampled and fed to the executive's thermal control;
//! * `usb` / `cdc`: USB CDC-ACM on the board's USB port; `uart`: the TFT header (USART1,
//!   115200 Bd). Both feed `Printer::receive`; every output line goes to both.
//!
//! Bring-up, in order: VTOR is set to the image base 0x08008000 by cortex-m-rt's reset handler
//! (`set-vtor`; the bootloader's table is never used), clocks (8 MHz HSE → 168 MHz, 48 MHz USB),
//! pins with heaters off and drivers disabled, SAFE_POWER (PC13) driven high for the program's
//! life, the TMC2209 drivers configured and read back over UART (a driver that does not answer
//! halts the printer with an `Error:` line: motion stays disabled), then the tasks and the
//! independent watchdog (2 s), fed only while both the motion and the heater loops beat
//! (`firmware::drivers::Liveness`).
//!
//! defmt logs over RTT. A panic or HardFault turns every heater off, disables the drivers and
//! cuts their power (raw register writes), and writes one line on the TFT UART (USB cannot be
//! served any more: a USB host sees the link stop).
//!
//! On the host this file compiles to an empty program (`cargo test --workspace` never builds
//! embassy).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

#[cfg(target_os = "none")]
mod image {
    use core::cell::RefCell;

    use defmt_rtt as _;
    use embassy_executor::Spawner;
    use embassy_futures::join::join;
    use embassy_futures::select::{select, Either};
    use embassy_stm32::adc::{Adc, SampleTime};
    use embassy_stm32::gpio::Input;
    use embassy_stm32::usart::{BufferedUart, Config as UartConfig};
    use embassy_stm32::usb::Driver;
    use embassy_stm32::wdg::IndependentWatchdog;
    use embassy_stm32::{bind_interrupts, peripherals, usart, usb};
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::pipe::Pipe;
    use embassy_time::{Duration, Ticker, Timer};
    use embassy_usb::class::cdc_acm::{CdcAcmClass, State as CdcState};
    use embassy_usb::UsbDevice;
    use firmware::config::MachineConfig;
    use firmware::homing::{HomingConfig, PinEndstops};
    use firmware::link::PortId;
    use firmware::motion::{Axis, Realtime};
    use firmware::printer::{DriverRequest, Printer, State, StepperRequest};
    use firmware::stepgen::StepEvent;
    use firmware::thermal::HeaterId;
    use heapless::spsc::Producer;
    use static_cell::StaticCell;

    use crate::board::drivers::adc::{AdcChannels, Oversampler};
    use crate::board::drivers::homing_watch::EventFlags;
    use crate::board::drivers::{IdleTimeout, PauseButton, StepperPins};
    use crate::board::heaters::{self, Fans, SoftPwm, PWM_SLOTS};
    use crate::board::stepper::{self, PinEvent, LOOKAHEAD_NS};
    use crate::board::{clock, pins, safety, tmc};
    use firmware::drivers::tmc2209::DriverSettings;
    use firmware::drivers::Liveness;

    bind_interrupts!(struct Irqs {
        OTG_FS => usb::InterruptHandler<peripherals::USB_OTG_FS>;
        USART1 => usart::BufferedInterruptHandler<peripherals::USART1>;
    });

    /// Stepper drivers switch off after this long without motion (Marlin's default 120 s).
    const STEPPER_IDLE_S: u32 = 120;
    /// Baud rate of the TFT header.
    const UART_BAUD: u32 = 115_200;
    /// Host-link bytes buffered per output port.
    const OUT_PIPE: usize = 1024;

    type Shared = &'static RefCell<Printer>;

    /// Independent watchdog timeout, µs (Marlin's STM32 `WDT_TIMEOUT_US` is 4 s; 2 s still
    /// covers the longest blocking section, configuring four drivers at about 120 ms each).
    const WATCHDOG_US: u32 = 2_000_000;
    /// Each of the motion and heater loops must beat this often for the watchdog to be fed, µs.
    const LIVENESS_GAP_US: u64 = 250_000;
    /// The loops the watchdog watches.
    const LOOP_MOTION: usize = 0;
    const LOOP_HEATERS: usize = 1;

    static LIVENESS: critical_section::Mutex<core::cell::RefCell<Liveness<2>>> =
        critical_section::Mutex::new(core::cell::RefCell::new(Liveness::new(LIVENESS_GAP_US)));

    fn beat(i: usize) {
        let now = printer_now_us();
        critical_section::with(|cs| LIVENESS.borrow(cs).borrow_mut().beat(i, now));
    }

    /// The four TMC2209 drivers and what was last written to each (None: not configured).
    struct Drivers {
        tmc: [tmc::Driver; 4],
        applied: [Option<DriverSettings>; 4],
    }

    static PRINTER: StaticCell<RefCell<Printer>> = StaticCell::new();
    static USB_OUT: Pipe<CriticalSectionRawMutex, OUT_PIPE> = Pipe::new();
    static UART_OUT: Pipe<CriticalSectionRawMutex, OUT_PIPE> = Pipe::new();

    /// The executive's clock, ns (the board's TIM5 time base).
    fn printer_now_ns() -> u64 {
        clock::now_ns()
    }

    fn printer_now_us() -> u64 {
        printer_now_ns() / 1000
    }

    fn steps(cfg: &MachineConfig, axis: Axis, mm: f32) -> i32 {
        let v = libm::roundf(mm * cfg.axis(axis).steps_per_mm);
        if v.is_finite() {
            v.clamp(i32::MIN as f32, i32::MAX as f32) as i32
        } else {
            0
        }
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let mut config = embassy_stm32::Config::default();
        {
            use embassy_stm32::rcc::*;
            use embassy_stm32::time::Hertz;
            // 8 MHz crystal → 168 MHz SYSCLK, 48 MHz for USB.
            config.rcc.hse = Some(Hse {
                freq: Hertz(pins::HSE_HZ),
                mode: HseMode::Oscillator,
            });
            config.rcc.pll_src = PllSource::HSE;
            config.rcc.pll = Some(Pll {
                prediv: PllPreDiv::DIV4,
                mul: PllMul::MUL168,
                divp: Some(PllPDiv::DIV2),
                divq: Some(PllQDiv::DIV7),
                divr: None,
            });
            config.rcc.ahb_pre = AHBPrescaler::DIV1;
            config.rcc.apb1_pre = APBPrescaler::DIV4;
            config.rcc.apb2_pre = APBPrescaler::DIV2;
            config.rcc.sys = Sysclk::PLL1_P;
            config.rcc.mux.clk48sel = mux::Clk48sel::PLL1_Q;
        }
        let p = embassy_stm32::init(config);
        let (pins, periph) = pins::split(p);
        // SAFE_POWER: embassy's `Output` puts the pin back to analog when dropped, which would
        // cut the drivers' and FETs' supply; it stays driven high for the program's life.
        core::mem::forget(pins.safe_power);
        // cortex-m-rt set VTOR in its reset handler (feature `set-vtor`); check it.
        // SAFETY: a read of the SCB's VTOR register.
        let vtor = unsafe { (*cortex_m::peripheral::SCB::PTR).vtor.read() };
        defmt::info!("SKR 2 up at 168 MHz, VTOR {=u32:#010x}", vtor);
        clock::start(periph.step_timer);

        let cfg = MachineConfig::ENDER3;
        let printer = PRINTER.init(RefCell::new(Printer::new(cfg)));
        // G28 homes through the planner on the X/Y/Z minimum switches (Marlin's Ender-3 homing
        // feeds, bump and Z raise). Moves of an axis before it is homed are refused by the step
        // interrupt (Marlin's NO_MOTION_BEFORE_HOMING), G28's own moves excepted.
        printer.borrow_mut().enable_endstops(HomingConfig::ENDER3);
        announce_reset_cause(printer);
        // Saved settings (M500) replace the factory ones; M500/M501 run in their own task.
        crate::board::flash::start(&spawner, printer);
        // The micro-SD slot: SD printing (M20–M32), in its own task.
        crate::board::sd::start(&spawner, printer);

        let steppers = StepperPins::new(
            pins.step,
            pins.dir,
            pins.enable,
            cfg.dir_high_positive_mask(),
        );
        let [x_min, y_min, z_min] = pins.endstops;
        let endstops = PinEndstops {
            x: x_min,
            y: y_min,
            z: z_min,
            // Ender-3 switches on pulled-up inputs read high when pressed.
            pressed_high: cfg.endstop_hit_high_mask(),
        };
        let producer = stepper::init(steppers, endstops);
        stepper::with(|s| s.exec.limits = limits_steps(&cfg));

        // USB CDC-ACM.
        static EP_OUT: StaticCell<[u8; 256]> = StaticCell::new();
        static CONFIG_DESC: StaticCell<[u8; 256]> = StaticCell::new();
        static BOS_DESC: StaticCell<[u8; 256]> = StaticCell::new();
        static CONTROL: StaticCell<[u8; 64]> = StaticCell::new();
        static CDC_STATE: StaticCell<CdcState> = StaticCell::new();
        let mut usb_config = usb::Config::default();
        usb_config.vbus_detection = false;
        let (usb_p, dp, dm) = periph.usb;
        let driver = Driver::new_fs(usb_p, Irqs, dp, dm, EP_OUT.init([0; 256]), usb_config);
        let mut dev = embassy_usb::Config::new(0x0483, 0x5740);
        dev.manufacturer = Some("pause firmware");
        dev.product = Some("SKR 2 printer");
        dev.serial_number = Some("skr2");
        dev.max_power = 100;
        dev.max_packet_size_0 = 64;
        let mut builder = embassy_usb::Builder::new(
            driver,
            dev,
            CONFIG_DESC.init([0; 256]),
            BOS_DESC.init([0; 256]),
            &mut [],
            CONTROL.init([0; 64]),
        );
        let cdc = CdcAcmClass::new(&mut builder, CDC_STATE.init(CdcState::new()), 64);
        let usb_dev = builder.build();

        // TFT header UART.
        static UART_TX: StaticCell<[u8; 512]> = StaticCell::new();
        static UART_RX: StaticCell<[u8; 512]> = StaticCell::new();
        let mut ucfg = UartConfig::default();
        ucfg.baudrate = UART_BAUD;
        let (uart_p, rx, tx) = periph.uart;
        let uart = BufferedUart::new(
            uart_p,
            rx,
            tx,
            UART_TX.init([0; 512]),
            UART_RX.init([0; 512]),
            Irqs,
            ucfg,
        );

        spawn(&spawner, usb_task(usb_dev));
        spawn(&spawner, cdc_task(cdc, printer));
        match uart {
            Ok(uart) => spawn(&spawner, uart_task(uart, printer)),
            Err(_) => defmt::error!("TFT UART configuration rejected"),
        }
        spawn(
            &spawner,
            heater_task(
                printer,
                periph.adc,
                SoftPwm::new(pins.heater_hotend),
                SoftPwm::new(pins.heater_bed),
                Fans::new(periph.fans.0, periph.fans.1, periph.fans.2),
            ),
        );
        // The drivers, before any motion: a driver that does not answer halts the printer.
        let [tx, ty, tz, te] = pins.tmc_uart;
        let mut drivers = Drivers {
            tmc: [
                tmc::driver(tx),
                tmc::driver(ty),
                tmc::driver(tz),
                tmc::driver(te),
            ],
            applied: [None; 4],
        };
        configure_drivers(printer, &mut drivers, 0b1111);
        spawn(
            &spawner,
            motion_task(
                printer,
                producer,
                pins.pause_button,
                pins.status_led,
                drivers,
            ),
        );
        spawn(
            &spawner,
            watchdog_task(IndependentWatchdog::new(periph.watchdog, WATCHDOG_US)),
        );
    }

    /// A fault or watchdog reset before this start-up is said on every port (queued until a
    /// host reads it), as Marlin reports a watchdog reset.
    fn announce_reset_cause(printer: Shared) {
        if let Some(cause) = safety::reset_cause() {
            defmt::warn!("reset cause: {}", cause);
            printer.borrow_mut().board_notice(cause);
        }
    }

    /// Spawns a task; a task that cannot be spawned (pool exhausted) is logged, not a panic.
    fn spawn<S>(
        spawner: &Spawner,
        token: Result<embassy_executor::SpawnToken<S>, embassy_executor::SpawnError>,
    ) {
        match token {
            Ok(t) => spawner.spawn(t),
            Err(_) => defmt::error!("task could not be spawned"),
        }
    }

    /// Configures the drivers in `mask` with the executive's settings for them, reports each
    /// outcome on the host link, and halts the printer if any does not answer or hold its
    /// settings (motion stays disabled: the halted motion loop keeps the drivers off).
    fn configure_drivers(printer: Shared, d: &mut Drivers, mask: u8) {
        let mut p = printer.borrow_mut();
        let mut ok = true;
        for (i, axis) in Axis::ALL.into_iter().enumerate() {
            if mask & (1 << i) == 0 {
                continue;
            }
            let s = p.driver_settings(axis);
            let r = d.tmc[i].configure(&s);
            d.applied[i] = r.ok().map(|_| s);
            if let Err(e) = r {
                defmt::error!("TMC2209 {}: {}", i, defmt::Display2Format(&e));
                ok = false;
            }
            p.driver_configured(axis, r);
        }
        if !ok {
            p.request(Realtime::EmergencyStop, printer_now_us());
        }
    }

    /// Serves the executive's driver requests and re-applies a driver whose settings changed
    /// (M906, M569, M350, M501/M502), only while nothing moves.
    fn service_drivers(printer: Shared, d: &mut Drivers) {
        let mut reports = 0u8;
        while let Some(r) = printer.borrow_mut().take_driver_request() {
            if let DriverRequest::Report { mask } = r {
                reports |= mask;
            }
        }
        let mut changed = 0u8;
        {
            let p = printer.borrow();
            for (i, axis) in Axis::ALL.into_iter().enumerate() {
                if d.applied[i].is_some_and(|a| a != p.driver_settings(axis)) {
                    changed |= 1 << i;
                }
            }
        }
        if changed != 0 {
            configure_drivers(printer, d, changed);
        }
        for (i, axis) in Axis::ALL.into_iter().enumerate() {
            if reports & (1 << i) != 0 {
                let r = d.tmc[i].report();
                printer.borrow_mut().driver_report(axis, r);
            }
        }
    }

    /// Feeds the independent watchdog every 50 ms while the motion and heater loops are alive.
    #[embassy_executor::task]
    async fn watchdog_task(mut wdg: IndependentWatchdog<'static, peripherals::IWDG>) {
        wdg.unleash();
        let mut ticker = Ticker::every(Duration::from_millis(50));
        loop {
            ticker.next().await;
            let now = printer_now_us();
            if critical_section::with(|cs| LIVENESS.borrow(cs).borrow().all_alive(now)) {
                wdg.pet();
            } else {
                defmt::warn!("a loop is late: watchdog not fed");
            }
        }
    }

    /// Pushes each port's pending host-link output to its pipe (USB, TFT UART), as far as the
    /// pipe has room; the executive keeps the rest in that port's output ring.
    fn flush_output(p: &mut Printer) {
        let mut buf = [0u8; 128];
        for (port, pipe) in [(PortId::Usb, &USB_OUT), (PortId::Tft, &UART_OUT)] {
            loop {
                let room = pipe.free_capacity().min(buf.len());
                let n = p.read_output_on(port, buf.get_mut(..room).unwrap_or(&mut []));
                if n == 0 {
                    break;
                }
                let _ = pipe.try_write(buf.get(..n).unwrap_or(&[]));
            }
        }
    }

    /// Queues the executive's step events up to [`LOOKAHEAD_NS`] ahead, each with its homing
    /// flags (a homing move, the switch that ends it). `held` is an event taken from the
    /// executive that did not fit in the queue (queued first next time).
    fn feed_steps(
        p: &mut Printer,
        producer: &mut Producer<'static, PinEvent>,
        held: &mut Option<(StepEvent, EventFlags)>,
    ) {
        let now = printer_now_ns();
        let to_pin = |ev: &StepEvent, flags: EventFlags| PinEvent {
            t_ticks: ev.t_ns / clock::NS_PER_TICK,
            axis_mask: ev.axis_mask,
            dir_mask: ev.dir_mask,
            flags,
        };
        let mut queued = false;
        if let Some((ev, flags)) = held.take() {
            if producer.enqueue(to_pin(&ev, flags)).is_err() {
                *held = Some((ev, flags));
                return;
            }
            queued = true;
        }
        while producer.ready() {
            let Some(t) = p.next_step_ns() else { break };
            if t > now + LOOKAHEAD_NS {
                break;
            }
            let Some(ev) = p.next_step() else { break };
            let flags = EventFlags::of(p, &ev);
            if producer.enqueue(to_pin(&ev, flags)).is_err() {
                *held = Some((ev, flags));
                break;
            }
            queued = true;
        }
        if queued {
            stepper::with(|s| s.exec.pins.set_enabled(true));
            stepper::kick();
        }
    }

    /// Software limits of X, Y, Z in steps, and their home (minimum) positions.
    fn limits_steps(cfg: &MachineConfig) -> [(i32, i32); 3] {
        [Axis::X, Axis::Y, Axis::Z].map(|a| {
            (
                steps(cfg, a, cfg.axis(a).min_mm),
                steps(cfg, a, cfg.axis(a).max_mm),
            )
        })
    }

    /// G28 on the board, before `Printer::poll` each tick: an approach the step interrupt
    /// stopped at its switch goes to the executive with what was never stepped (the held event
    /// included); the executive learns whether events are still in flight (homing decides on
    /// a move's end only after its last step) and the switches' states (M119).
    fn homing_before_poll(p: &mut Printer, held: &mut Option<(StepEvent, EventFlags)>) {
        if let Some(mut trip) = stepper::take_trip() {
            if let Some((ev, _)) = held.take() {
                trip.add(ev.axis_mask, ev.dir_mask);
            }
            defmt::info!("endstop {} hit", trip.axis.index());
            p.endstop_trip(trip.axis, trip.undone);
        }
        let in_flight = stepper::with(|s| {
            p.sample_endstops(&mut s.endstops);
            s.in_flight()
        })
        .unwrap_or(false);
        p.set_steps_in_flight(in_flight || held.is_some());
    }

    /// After `Printer::poll`, before new events are queued: the step interrupt follows the
    /// executive's homed axes (an axis homed in this poll is at its minimum).
    fn homing_after_poll(p: &mut Printer) {
        let fresh = p.take_homed();
        let homed = p.homed_axes();
        let home = limits_steps(p.config()).map(|(min, _)| min);
        stepper::with(|s| s.exec.set_homed(homed, fresh, home));
    }

    #[embassy_executor::task]
    async fn motion_task(
        printer: Shared,
        mut producer: Producer<'static, PinEvent>,
        button_pin: Input<'static>,
        mut led: embassy_stm32::gpio::Output<'static>,
        mut drivers: Drivers,
    ) {
        let mut ticker = Ticker::every(Duration::from_millis(1));
        let mut button = PauseButton::new();
        let mut idle = IdleTimeout::new(STEPPER_IDLE_S);
        let mut pending_disable: Option<u8> = None;
        let mut halted = false;
        let mut blink: u32 = 0;
        let mut held: Option<(StepEvent, EventFlags)> = None;
        loop {
            ticker.next().await;
            beat(LOOP_MOTION);
            let now_us = printer_now_us();
            {
                let mut p = printer.borrow_mut();
                let state = p.state();
                let paused = matches!(state, State::Paused | State::Pausing);
                if let Some(req) = button.update(button_pin.is_low(), now_us, paused) {
                    defmt::info!("pause button: {}", defmt::Debug2Format(&req));
                    p.request(req, now_us);
                }
                homing_before_poll(&mut p, &mut held);
                p.poll(now_us);
                homing_after_poll(&mut p);
                if p.state() == State::Halted {
                    if !halted {
                        halted = true;
                        defmt::error!("halted: motion stopped, heaters off");
                        stepper::with(|s| {
                            s.flush = true;
                            s.exec.pins.set_enabled(false);
                        });
                        stepper::kick();
                    }
                } else {
                    feed_steps(&mut p, &mut producer, &mut held);
                }
                let running = stepper::with(|s| s.running).unwrap_or(false);
                // M17/M18/M84 from the executive, in job order. A disable waits until the
                // step queue has run dry (the executive issues it once the planner is done;
                // up to 2 ms of steps may still be queued here).
                if pending_disable.is_none() {
                    while let Some(r) = p.take_stepper_request() {
                        match r {
                            StepperRequest::Enable { mask } => {
                                stepper::with(|s| s.exec.pins.set_axes_enabled(mask, true));
                            }
                            StepperRequest::Disable { mask } => {
                                pending_disable = Some(mask);
                                break;
                            }
                            StepperRequest::IdleTimeout { s } => idle.set_timeout_s(s),
                        }
                    }
                }
                if let Some(mask) = pending_disable {
                    if !running {
                        pending_disable = None;
                        let on = stepper::with(|s| {
                            s.exec.pins.set_axes_enabled(mask, false);
                            s.exec.pins.enabled_mask()
                        })
                        .unwrap_or(0);
                        defmt::info!(
                            "steppers disabled: {=u8:#06b}, still on: {=u8:#06b}",
                            mask,
                            on
                        );
                    }
                }
                let busy = p.state() != State::Idle || running;
                if idle.update(busy, now_us) {
                    stepper::with(|s| s.exec.pins.set_enabled(false));
                }
                if let Some(n) = stepper::with(|s| core::mem::take(&mut s.exec.refused)) {
                    if n > 0 {
                        defmt::warn!("{} steps refused (not homed or outside the volume)", n);
                    }
                }
                flush_output(&mut p);
            }
            // The drivers' UART lines block the executor: only while nothing moves or is queued.
            let quiet = {
                let mut p = printer.borrow_mut();
                p.state() == State::Idle && p.next_step_ns().is_none()
            } && !stepper::with(|s| s.running).unwrap_or(false);
            if quiet && !halted {
                service_drivers(printer, &mut drivers);
            }
            blink = blink.wrapping_add(1);
            let period = if halted { 100 } else { 500 };
            if blink.is_multiple_of(period) {
                led.toggle();
            }
        }
    }

    /// The two thermistor inputs on ADC1 (channel 0: hotend TH0 on PA2, 1: bed TB on PA1),
    /// behind the portable polled-ADC seam. embassy-stm32's F4 ADC converts synchronously
    /// (≈ 23 µs at 480 cycles), so a read is always ready.
    struct ThermistorAdc {
        adc: Adc<'static, peripherals::ADC1>,
        hotend: embassy_stm32::Peri<'static, peripherals::PA2>,
        bed: embassy_stm32::Peri<'static, peripherals::PA1>,
    }

    impl AdcChannels for ThermistorAdc {
        type Error = core::convert::Infallible;
        fn read(&mut self, channel: u8) -> nb::Result<u16, Self::Error> {
            Ok(match channel {
                0 => self
                    .adc
                    .blocking_read(&mut self.hotend, SampleTime::CYCLES480),
                _ => self.adc.blocking_read(&mut self.bed, SampleTime::CYCLES480),
            })
        }
    }

    #[embassy_executor::task]
    async fn heater_task(
        printer: Shared,
        adc: (
            embassy_stm32::Peri<'static, peripherals::ADC1>,
            embassy_stm32::Peri<'static, peripherals::PA2>,
            embassy_stm32::Peri<'static, peripherals::PA1>,
        ),
        mut hotend: SoftPwm,
        mut bed: SoftPwm,
        mut fans: Fans,
    ) {
        let (adc1, th0, tb) = adc;
        let mut adc = ThermistorAdc {
            adc: Adc::new(adc1),
            hotend: th0,
            bed: tb,
        };
        let mut sampler: Oversampler<2> = Oversampler::new();
        let tables = heaters::tables();
        let mut ticker = Ticker::every(Duration::from_millis(1));
        let mut slot: u32 = 0;
        loop {
            ticker.next().await;
            beat(LOOP_HEATERS);
            // One conversion per tick, channels in turn: a reading of each every 32 ms, the
            // average of 16 conversions (the converter is synchronous: never WouldBlock here).
            let _ = sampler.poll(&mut adc);
            if slot == 0 {
                let (Some(raw_h), Some(raw_b)) = (sampler.latest(0), sampler.latest(1)) else {
                    hotend.tick(slot);
                    bed.tick(slot);
                    slot = (slot + 1) % PWM_SLOTS;
                    continue;
                };
                // Faults travel as ±∞ markers the thermal control understands.
                let c_h = tables[0].celsius_marked(raw_h);
                let c_b = tables[1].celsius_marked(raw_b);
                let now = printer_now_us();
                let mut p = printer.borrow_mut();
                let d_h = p.thermal_sample(HeaterId::Hotend, c_h, now);
                let d_b = p.thermal_sample(HeaterId::Bed, c_b, now);
                if p.state() == State::Halted {
                    hotend.off();
                    bed.off();
                } else {
                    hotend.set_duty(d_h);
                    bed.set_duty(d_b);
                }
                fans.set_hotend(p.thermal().hotend_fan_on());
                fans.set_part(p.fan_pwm());
            }
            hotend.tick(slot);
            bed.tick(slot);
            slot = (slot + 1) % PWM_SLOTS;
        }
    }

    #[embassy_executor::task]
    async fn usb_task(mut dev: UsbDevice<'static, Driver<'static, peripherals::USB_OTG_FS>>) {
        dev.run().await
    }

    #[embassy_executor::task]
    async fn cdc_task(
        class: CdcAcmClass<'static, Driver<'static, peripherals::USB_OTG_FS>>,
        printer: Shared,
    ) {
        let (mut tx, mut rx) = class.split();
        let receive = async {
            let mut buf = [0u8; 64];
            loop {
                rx.wait_connection().await;
                while let Ok(n) = rx.read_packet(&mut buf).await {
                    // Flow control: bytes the printer cannot take yet are offered again; the
                    // next packet is not read meanwhile, so the endpoint NAKs the host.
                    let mut data = buf.get(..n).unwrap_or(&[]);
                    loop {
                        let taken =
                            printer
                                .borrow_mut()
                                .receive_on(PortId::Usb, data, printer_now_us());
                        data = data.get(taken..).unwrap_or(&[]);
                        if data.is_empty() {
                            break;
                        }
                        Timer::after_millis(1).await;
                    }
                }
            }
        };
        let send = async {
            let mut buf = [0u8; 64];
            loop {
                tx.wait_connection().await;
                loop {
                    let n = USB_OUT.read(&mut buf).await;
                    let data = buf.get(..n).unwrap_or(&[]);
                    if tx.write_packet(data).await.is_err() {
                        break;
                    }
                }
            }
        };
        join(receive, send).await;
    }

    #[embassy_executor::task]
    async fn uart_task(uart: BufferedUart<'static>, printer: Shared) {
        use embedded_io_async::{Read, Write};
        let (mut tx, mut rx) = uart.split();
        let mut inbuf = [0u8; 64];
        let mut outbuf = [0u8; 64];
        loop {
            match select(rx.read(&mut inbuf), UART_OUT.read(&mut outbuf)).await {
                Either::First(Ok(n)) => {
                    // Port 1: its own line assembler, line numbers and `ok`s. Bytes not taken
                    // are offered again (the UART's RX buffer holds the rest meanwhile), while
                    // the answers keep flowing.
                    let mut data = inbuf.get(..n).unwrap_or(&[]);
                    loop {
                        let taken =
                            printer
                                .borrow_mut()
                                .receive_on(PortId::Tft, data, printer_now_us());
                        data = data.get(taken..).unwrap_or(&[]);
                        if data.is_empty() {
                            break;
                        }
                        match UART_OUT.try_read(&mut outbuf) {
                            Ok(k) => {
                                let _ = tx.write_all(outbuf.get(..k).unwrap_or(&[])).await;
                            }
                            Err(_) => Timer::after_millis(1).await,
                        }
                    }
                }
                Either::First(Err(_)) => {}
                Either::Second(n) => {
                    let _ = tx.write_all(outbuf.get(..n).unwrap_or(&[])).await;
                }
            }
        }
    }

    /// What a panic or HardFault says on the TFT UART (a Marlin-style kill message).
    const FATAL_LINE: &[u8] =
        b"\nError:firmware fault: heaters and drivers off, power cut. The board restarts\n";

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        // Heaters first, before anything that could fault again.
        safety::all_off();
        safety::record_fault(safety::Fault::Panic);
        safety::uart_say(FATAL_LINE);
        defmt::error!("panic: {}", defmt::Display2Format(info));
        safety::reset_or_break()
    }

    #[cortex_m_rt::exception]
    unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
        safety::all_off();
        safety::record_fault(safety::Fault::HardFault);
        safety::uart_say(FATAL_LINE);
        safety::reset_or_break()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {}
