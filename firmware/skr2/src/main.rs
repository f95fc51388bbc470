//! The BigTreeTech SKR 2 (STM32F407VG) image: embassy tasks around the portable executive
//! (`firmware::printer::Printer`).
//!
//! * `motion` (every 1 ms): `Printer::poll`, step events into the step interrupt's queue
//!   (`board::stepper`, TIM5 compare at the highest priority, re-timing late events), the endstops for G28 (homing
//!   runs through the planner: `firmware::homing`) and M119, the pause button, the stepper
//!   idle timeout, halt handling, host-link output to both ports;
//! * `heaters` (every 1 ms): 10 Hz software PWM of the heaters; every 100 ms the thermistors
//!   are sampled and fed to the executive's thermal control;
//! * `usb` / `cdc`: USB CDC-ACM on the board's USB port; `uart`: the TFT header (USART1,
//!   115200 Bd). Both pass their bytes to the motion task, which feeds `Printer::receive_on`,
//!   each port with its own line numbers and `ok`s: a command's answers go to the port it came
//!   from, notices (halts, `Error:` lines, start-up messages) to both;
//! * `card`: brings the micro-SD card up when the executive asks (the motion task serves the
//!   card and the flash store in turn).
//!
//! The executive has one owner, the motion task; the other tasks talk to it through embassy
//! pipes, channels and signals (`image/channels.rs` has the table). This file brings the board
//! up and spawns the tasks; the tasks live in `image/`: `motion.rs`, `heater.rs`, `host.rs`
//! (USB and UART), `drivers.rs` (the TMC2209s).
//!
//! Bring-up, in order: cortex-m-rt's reset handler sets SP and VTOR (`set-sp`, `set-vtor`: the
//! image base 0x08008000, whatever the bootloader left), runs [`__pre_init`] (SysTick off,
//! every NVIC interrupt disabled and unpended: nothing the bootloader armed can fire into this
//! image) and paints the stack (`paint-stack`); then the stack guard (MPU, `board::stack`),
//! clocks (8 MHz HSE → 168 MHz, 48 MHz USB), pins with heaters off and SAFE_POWER (PC13) low,
//! Marlin's reversed-driver check (`board::pins::check_sockets`: SAFE_POWER goes high only if
//! no driver module is plugged in backwards; otherwise `Error:X driver is backward!` and a
//! halt), the TMC2209 drivers configured and read back over UART (a driver that does not answer
//! halts the printer with an `Error:` line: motion stays disabled), the interrupt priorities
//! (the step timer above everything), then the tasks and the independent watchdog (2.5 s at
//! the fastest LSI, `board::watchdog`), fed only while both the motion and the heater loops
//! beat (`firmware::drivers::Liveness`).
//!
//! defmt logs over RTT. A panic, a HardFault (a stack overflow included) or any interrupt this
//! image does not use (`DefaultHandler`) turns every heater off, disables the drivers and cuts
//! their power (raw register writes), records why, and writes one line on the TFT UART (USB
//! cannot be served any more: a USB host sees the link stop and reads the reason after the
//! reset).
//!
//! On the host this file compiles to an empty program (`cargo test --workspace` never builds
//! embassy).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;

// Runs in cortex-m-rt's reset handler before RAM is initialised (so: assembly, no Rust):
// whatever the SD bootloader left armed must not fire into this image. SysTick off
// (SYST_CSR = 0, PM0214 §4.5); every NVIC interrupt disabled (ICER0–7) and its pending bit
// cleared (ICPR0–7, PM0214 §4.3; the F4 has 82/91 IRQs, 3 registers); SysTick and PendSV
// unpended (ICSR PENDSTCLR bit 25, PENDSVCLR bit 27); then PRIMASK and FAULTMASK cleared, in
// case the bootloader jumped here with interrupts masked (nothing is enabled to fire yet).
#[cfg(target_os = "none")]
core::arch::global_asm!(
    ".section .text.__pre_init, \"ax\"",
    ".global __pre_init",
    ".type __pre_init,%function",
    ".thumb_func",
    "__pre_init:",
    "ldr r0, =0xE000E010",
    "movs r1, #0",
    "str r1, [r0]",
    "ldr r0, =0xE000E180",
    "ldr r2, =0xE000E280",
    "ldr r1, =0xFFFFFFFF",
    "movs r3, #8",
    "1:",
    "str r1, [r0], #4",
    "str r1, [r2], #4",
    "subs r3, #1",
    "bne 1b",
    "ldr r0, =0xE000ED04",
    "ldr r1, =0x0A000000",
    "str r1, [r0]",
    "dsb",
    "isb",
    "cpsie i",
    "cpsie f",
    "bx lr",
);

#[cfg(target_os = "none")]
mod image {
    use defmt_rtt as _;
    use embassy_executor::Spawner;
    use embassy_stm32::interrupt::{self, InterruptExt, Priority};
    use embassy_stm32::{bind_interrupts, peripherals, usart, usb};
    use embassy_time::{Duration, Ticker};
    use firmware::config::MachineConfig;
    use firmware::homing::{HomingConfig, PinEndstops};
    use firmware::printer::{Policy, Printer};
    use static_cell::StaticCell;

    use crate::board::drivers::StepperPins;
    use crate::board::heaters::{Fans, SoftPwm};
    use crate::board::{clock, flash, pins, safety, sd, stack, stepper, tmc, watchdog};
    use drivers::{configure_drivers, Drivers};
    use firmware::drivers::Liveness;
    use heater::heater_task;
    use host::{cdc_task, uart_task, usb_task};
    use motion::{halted_task, motion_task, Devices};

    // What the tasks say to each other.
    mod channels;
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
    /// The TFT UART driver's transmit and receive buffers, bytes.
    const UART_TX_BUF: usize = 512;
    const UART_RX_BUF: usize = 512;

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

    static PRINTER: StaticCell<Printer> = StaticCell::new();

    /// The executive's clock, ns (the board's TIM5 time base).
    fn printer_now_ns() -> u64 {
        clock::now_ns()
    }

    fn printer_now_us() -> u64 {
        printer_now_ns() / 1000
    }

    /// Interrupt priorities (NVIC_IPRx; the STM32F4 implements the top 4 bits: 16 levels,
    /// RM0090 §10.1 "16 programmable priority levels", PM0214 §4.3.7; embassy's `P0`–`P15`
    /// write them there). Lower is more urgent; an interrupt preempts only less urgent ones.
    /// The step timer alone at the top, so step edges are late only by the other interrupts'
    /// critical sections (`critical_section` masks all of them briefly).
    const PRIO_STEP: Priority = Priority::P0;
    /// The TFT UART: a byte every 87 µs at 115200 Bd, one byte of hardware buffer.
    const PRIO_UART: Priority = Priority::P1;
    /// embassy-time's driver (TIM2): wakes the 1 ms loops.
    const PRIO_TIME: Priority = Priority::P2;
    /// USB OTG FS, SDIO and its DMA stream (both have FIFOs and can wait).
    const PRIO_BULK: Priority = Priority::P3;

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        // Before anything can overflow the stack into the statics.
        stack::guard();
        let p = embassy_stm32::init(clock::chip_config(PRIO_BULK));
        clock::enable_flash_accelerator();
        interrupt::TIM2.set_priority(PRIO_TIME);
        let (mut pins, periph) = pins::split(p);
        // Marlin's reversed-driver check, SAFE_POWER low until it passes.
        let backward = pins::check_sockets(&mut pins.sockets, &mut pins.safe_power);
        // SAFE_POWER: embassy's `Output` puts the pin back to analog when dropped, which would
        // cut the drivers' and FETs' supply; it stays driven (high if the check passed, low
        // otherwise) for the program's life.
        core::mem::forget(pins.safe_power);
        // cortex-m-rt set VTOR in its reset handler (feature `set-vtor`); check it.
        // SAFETY: a read of the SCB's VTOR register.
        let vtor = unsafe { (*cortex_m::peripheral::SCB::PTR).vtor.read() };
        defmt::info!("SKR 2 up at 168 MHz, VTOR {=u32:#010x}", vtor);
        clock::start(periph.step_timer);

        let cfg = MachineConfig::ENDER3;
        // Built in place in its static: `init(Printer::new(..))` built the 35 KiB `Printer` on
        // the stack and copied it (a 72 KiB frame for this function, over half the RAM).
        // From here on it has one owner: this function until the motion task takes it.
        let printer = Printer::init_in_place(PRINTER.uninit(), cfg, Policy::FIRMWARE);
        // G28 homes through the planner on the X/Y/Z minimum switches (Marlin's Ender-3 homing
        // feeds, bump and Z raise). Axes not homed move from where they stood (Marlin's
        // default); the step interrupt's limits guard homed axes.
        printer.enable_endstops(HomingConfig::ENDER3);
        announce_reset_cause(printer);
        // Saved settings (M500) replace the factory ones; the motion task serves M500/M501.
        let store = flash::start(printer);
        // The micro-SD slot: SD printing (M20–M32); its task brings the card up.
        let card = sd::start(&spawner, printer);

        // The host ports: USB CDC-ACM and the TFT header's UART.
        let (usb_dev, cdc) = host::usb_port(periph.usb);
        let uart = host::tft_port(periph.uart);

        // Every interrupt below the step timer (the drivers above enabled theirs).
        interrupt::OTG_FS.set_priority(PRIO_BULK);
        interrupt::USART1.set_priority(PRIO_UART);
        interrupt::SDIO.set_priority(PRIO_BULK);
        interrupt::DMA2_STREAM3.set_priority(PRIO_BULK);

        spawn(&spawner, usb_task(usb_dev));
        spawn(&spawner, cdc_task(cdc));
        match uart {
            Ok(uart) => spawn(&spawner, uart_task(uart)),
            Err(_) => defmt::error!("TFT UART configuration rejected"),
        }
        spawn(
            &spawner,
            heater_task(
                periph.adc,
                SoftPwm::new(pins.heater_hotend),
                SoftPwm::new(pins.heater_bed),
                Fans::new(periph.fans.0, periph.fans.1, periph.fans.2),
            ),
        );
        if !backward.none() {
            // A module plugged in backwards: its drivers never get power. Report (Marlin's
            // words, every port), halt; the sockets' pins stay undriven.
            let mut names: heapless::Vec<&str, { pins::SOCKETS }> = heapless::Vec::new();
            for (i, name) in pins::SOCKET_NAMES.into_iter().enumerate() {
                if backward.socket(i) {
                    let _ = names.push(name);
                    defmt::error!("driver {} is backward: SAFE_POWER kept off", name);
                }
            }
            printer.drivers_backward(&names);
            spawn(&spawner, halted_task(printer, pins.status_led));
            start_watchdog(&spawner, periph.watchdog);
            return;
        }
        let (step, dir, enable) = pins::stepper_outputs(pins.sockets);
        let steppers = StepperPins::new(step, dir, enable, cfg.dir_high_positive_mask());
        let [x_min, y_min, z_min] = pins.endstops;
        let endstops = PinEndstops {
            x: x_min,
            y: y_min,
            z: z_min,
            // Ender-3 switches on pulled-up inputs read high when pressed.
            pressed_high: cfg.endstop_hit_high_mask(),
        };
        let producer = stepper::init(steppers, endstops, PRIO_STEP);
        stepper::with(|s| s.exec.follow(&printer.travel_frame()));

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
                Devices {
                    store,
                    card,
                    out_tick: 0,
                    pending_since: None,
                },
                producer,
                pins.pause_button,
                pins.status_led,
                drivers,
            ),
        );
        start_watchdog(&spawner, periph.watchdog);
    }

    /// Starts the independent watchdog and the task that feeds it.
    fn start_watchdog(spawner: &Spawner, iwdg: embassy_stm32::Peri<'static, peripherals::IWDG>) {
        watchdog::start(iwdg);
        defmt::info!(
            "watchdog: {=u64} ms at the fastest LSI, {=u64} ms at the slowest",
            watchdog::TIMING.map_or(0, |t| t.timeout_us(firmware::drivers::watchdog::LSI_MAX_HZ)
                / 1000),
            watchdog::max_timeout_us() / 1000
        );
        spawn(spawner, watchdog_task());
    }

    /// A fault or watchdog reset before this start-up is said on every port (queued until a
    /// host reads it), as Marlin reports a watchdog reset.
    fn announce_reset_cause(printer: &mut Printer) {
        if let Some(cause) = safety::reset_cause() {
            let mut t: heapless::String<160> = heapless::String::new();
            let _ = core::fmt::Write::write_fmt(&mut t, format_args!("{cause}"));
            defmt::warn!("reset cause: {}", t.as_str());
            printer.board_notice(&t);
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
    async fn watchdog_task() {
        let mut ticker = Ticker::every(Duration::from_millis(50));
        loop {
            ticker.next().await;
            let now = printer_now_us();
            if critical_section::with(|cs| LIVENESS.borrow(cs).borrow().all_alive(now)) {
                watchdog::feed();
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

    /// Every fault this image does not handle otherwise (MemManage, BusFault and UsageFault
    /// are not enabled, so they escalate here), a stack overflow into the guard included:
    /// this runs at priority −1, where the MPU is off, so its own stacking lands in the guard.
    #[cortex_m_rt::exception]
    unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
        safety::all_off();
        let sp = frame as *const cortex_m_rt::ExceptionFrame as u32;
        safety::record_fault(if stack::overflowed(sp) {
            safety::Fault::StackOverflow
        } else {
            safety::Fault::HardFault
        });
        safety::uart_say(FATAL_LINE);
        safety::reset_or_break()
    }

    /// Any exception or interrupt without a handler of its own (one this image never enables,
    /// a SysTick left running by a bootloader, a spurious IRQ): the same safe state as a
    /// HardFault instead of cortex-m-rt's endless loop (which would leave a heater on).
    #[cortex_m_rt::exception]
    unsafe fn DefaultHandler(irqn: i16) -> ! {
        safety::all_off();
        safety::record_fault(safety::Fault::Unexpected(irqn));
        safety::uart_say(FATAL_LINE);
        safety::reset_or_break()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {}
