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
//! This file brings the board up and spawns the tasks; the tasks live in `image/`: `motion.rs`,
//! `heater.rs`, `host.rs` (USB and UART), `drivers.rs` (the TMC2209s).
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
    use embassy_stm32::usart::{BufferedUart, Config as UartConfig};
    use embassy_stm32::usb::Driver;
    use embassy_stm32::wdg::IndependentWatchdog;
    use embassy_stm32::{bind_interrupts, peripherals, usart, usb};
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::pipe::Pipe;
    use embassy_time::{Duration, Ticker};
    use embassy_usb::class::cdc_acm::{CdcAcmClass, State as CdcState};
    use firmware::config::MachineConfig;
    use firmware::homing::{HomingConfig, PinEndstops};
    use firmware::printer::Printer;
    use static_cell::StaticCell;

    use crate::board::drivers::StepperPins;
    use crate::board::heaters::{Fans, SoftPwm};
    use crate::board::{clock, pins, safety, stepper, tmc};
    use drivers::{configure_drivers, Drivers};
    use firmware::drivers::Liveness;
    use heater::heater_task;
    use host::{cdc_task, uart_task, usb_task};
    use motion::{limits_steps, motion_task};

    // The TMC2209 drivers' configuration and reports.
    mod drivers;
    // Thermistors, heater PWM and fans.
    mod heater;
    // The USB and TFT host ports.
    mod host;
    // The 1 ms motion loop.
    mod motion;

    bind_interrupts!(struct Irqs {
        OTG_FS => usb::InterruptHandler<peripherals::USB_OTG_FS>;
        USART1 => usart::BufferedInterruptHandler<peripherals::USART1>;
    });

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
