//! The JSON report of a run (`scripts/board-emu.sh --json OUT`): everything from what the
//! emulated board's pins, UART and chip did, nothing from the image's own accounts.

use crate::axes::Axes;
use crate::cpu::Emulator;
use crate::cycles::ClockModel;
use crate::nvic::{exc, irq};
use crate::rcc::ResetKind;
use crate::time::{ns_from_cyc, s_from_cyc, Cyc, CPU_HZ};
use crate::usbhost::{DeviceInfo, UsbStats};
use serde::Serialize;
use std::collections::BTreeMap;

/// What `--serve` adds to the report.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ServeReport {
    /// The pseudo-terminals.
    pub usb_device: String,
    /// See `usb_device`.
    pub tft_device: String,
    /// Lines the image sent on USB and on the TFT UART (the last 10,000 of each).
    pub usb_lines: Vec<String>,
    /// See `usb_lines`.
    pub tft_lines: Vec<String>,
    /// A program opened (true) or closed the USB port, at virtual s.
    pub usb_sessions: Vec<(f64, bool)>,
    /// Virtual seconds per wall second over the run.
    pub virtual_per_wall: f64,
    /// Largest lag of virtual time behind the wall clock, s.
    pub lag_max_s: f64,
    /// Lag given up (virtual time that never ran), s.
    pub lag_dropped_s: f64,
    /// How the run ended.
    pub ended_by: String,
}

/// The USB host's account of the run.
#[derive(Clone, Debug, Serialize)]
pub struct UsbReport {
    /// The device as enumerated (descriptors, the CDC ACM function's endpoints).
    pub device: Option<DeviceInfo>,
    /// Configured at the end.
    pub configured: bool,
    /// DTR at the end (a program holds the port and the device was told).
    pub dtr: bool,
    /// Counts of resets, enumerations, packets, NAKs, bytes.
    pub stats: UsbStats,
    /// What happened on the bus, with its time (s).
    pub events: Vec<(f64, String)>,
    /// Transfers that failed.
    pub errors: Vec<String>,
}

/// The USB host's account, from the board's host model.
pub fn usb_report(b: &crate::board::Board) -> UsbReport {
    UsbReport {
        device: b.usb.device.clone(),
        configured: b.usb.configured,
        dtr: b.usb.dtr,
        stats: b.usb.stats.clone(),
        events: b
            .usb
            .events
            .iter()
            .map(|(t, e)| (s_from_cyc(*t), e.clone()))
            .collect(),
        errors: b.usb.errors.clone(),
    }
}

/// A value per axis, keyed X, Y, Z, E.
pub type PerAxis<T> = BTreeMap<&'static str, T>;

const AXES: [&str; 4] = ["X", "Y", "Z", "E"];

fn per_axis<T>(f: impl Fn(usize) -> T) -> PerAxis<T> {
    AXES.iter().enumerate().map(|(i, n)| (*n, f(i))).collect()
}

/// A reset the board went through.
#[derive(Clone, Debug, Serialize)]
pub struct ResetEntry {
    /// When, s.
    pub t_s: f64,
    /// Why.
    pub kind: ResetKind,
}

/// A fault the core took (HardFault entry) or a lockup.
#[derive(Clone, Debug, Serialize)]
pub struct FaultEntry {
    /// When, s.
    pub t_s: f64,
    /// What the core met.
    pub what: String,
}

/// What happened after an injected fault.
#[derive(Clone, Debug, Default, Serialize)]
pub struct AfterFault {
    /// Injected at, s.
    pub injected_s: f64,
    /// Heaters and drivers were all off this long after the injection (None: never), ms.
    pub safe_after_ms: Option<f64>,
    /// A heater was powered at the injection.
    pub heater_on_at_injection: bool,
    /// The first reset after the injection, s after it.
    pub reset_after_s: Option<f64>,
}

/// The report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The reply to M115 (the `FIRMWARE_NAME` line).
    pub m115: Option<String>,
    /// Every line the printer sent on USART1.
    pub lines: Vec<String>,
    /// When each of those lines was received, s.
    pub line_times_s: Vec<f64>,
    /// Signed steps per axis, from the DIR level at each rising STEP edge, from power-on.
    pub net_steps: PerAxis<i64>,
    /// The pause point (X Y Z E steps, the frame of `net_steps`; `sim run --json`'s
    /// `pause_point_steps` counts from the same origin when the carriage starts at the
    /// switches' home): where the park sequence (E retract, Z lift, XY travel) began.
    pub pause_point_steps: Option<[i64; 4]>,
    /// A pause requested with `--pause-request-after`: when (virtual s), and when the job's
    /// first step was (the request's reference).
    pub pause_requested_s: Option<f64>,
    /// See `pause_requested_s`.
    pub first_job_step_s: Option<f64>,
    /// When the park began (its first move, after the job's last step), virtual s.
    pub park_began_s: Option<f64>,
    /// When the printer said `//action:paused` (the park done), virtual s.
    pub parked_s: Option<f64>,
    /// The pause point in the `net_steps` frame (from the carriage's power-on position).
    pub pause_point_net_steps: Option<[i64; 4]>,
    /// Where the head was parked (`net_steps` frame).
    pub parked_steps: Option<[i64; 4]>,
    /// The steps of the last 3 s before the park ended, as runs in time order (start s, X and
    /// Y / Z+ / Z- / E+ / E-, the run's net steps X Y Z E): what the pause point was found
    /// from.
    pub park_moves: Vec<(f64, String, [i64; 4])>,
    /// The first runs of steps in one direction per axis (a homing's approach, bump, slow
    /// approach), with their rates.
    pub runs: PerAxis<Vec<crate::axes::Run>>,
    /// Shortest STEP high time, ns.
    pub min_step_high_ns: PerAxis<Option<u64>>,
    /// Shortest DIR change to STEP rise, ns.
    pub min_dir_setup_ns: PerAxis<Option<u64>>,
    /// Highest step rate (1 / the shortest interval between rising edges), Hz.
    pub max_step_rate_hz: PerAxis<Option<f64>>,
    /// The axis's own limit: max feed × steps/mm (`MachineConfig::ENDER3`), Hz.
    pub step_rate_limit_hz: PerAxis<f64>,
    /// Worst delay of a step edge after the TIM5 compare time the image armed for it, ns.
    pub step_schedule_deviation_max_ns: Option<u64>,
    /// Compare times armed (CCR1 writes) and how many were followed by a step within 50 µs.
    pub step_compares: (usize, usize),
    /// Deepest stack use, bytes (painted at power-on, scanned at the end).
    pub stack_high_water_bytes: Option<u32>,
    /// The stack's size, bytes.
    pub stack_size_bytes: Option<u32>,
    /// Resets by the independent watchdog.
    pub watchdog_resets: usize,
    /// Every reset after power-on.
    pub resets: Vec<ResetEntry>,
    /// Faults the core took.
    pub faults: Vec<FaultEntry>,
    /// After an injected fault.
    pub after_fault: Option<AfterFault>,
    /// Heaters powered at the end (hot end, bed).
    pub heaters_powered_at_end: [bool; 2],
    /// Drivers enabled at the end (X, Y, Z, E).
    pub drivers_enabled_at_end: [bool; 4],
    /// SAFE_POWER (PC13) high at the end.
    pub safe_power_at_end: bool,
    /// First time SAFE_POWER went high, s.
    pub safe_power_first_high_s: Option<f64>,
    /// Highest temperature of each heater, °C.
    pub max_temp_c: [f32; 2],
    /// Flash sector erases: (start s, sector, duration s).
    pub flash_erases: Vec<(f64, u32, f64)>,
    /// Hot end and bed powered during each of those erases.
    pub heaters_powered_during_erases: Vec<[bool; 2]>,
    /// The watchdog's timeout at this LSI, s (0 when never started).
    pub watchdog_timeout_s: f64,
    /// LSI frequency used, Hz.
    pub lsi_hz: u32,
    /// SD blocks read.
    pub sd_blocks_read: u64,
    /// TMC2209 datagrams each module took.
    pub tmc_datagrams: [u64; 4],
    /// Bytes the host sent that the UART dropped (overrun).
    pub uart_overruns: u64,
    /// Instructions executed.
    pub instructions: u64,
    /// The clock model the run used (`crate::cycles`).
    pub clock: ClockModel,
    /// Cycles the core was busy (instructions, wait states, refills, exception entries).
    pub busy_cycles: u64,
    /// Busy cycles per instruction.
    pub cycles_per_instruction: f64,
    /// Busy cycles beyond one per instruction: flash wait states (ART misses, literal
    /// reads), pipeline refills of taken branches, exception entries and returns.
    pub wait_state_cycles: u64,
    /// Of `wait_state_cycles`, those of literal reads (D-Code bus).
    pub literal_wait_cycles: u64,
    /// See `wait_state_cycles`.
    pub refill_cycles: u64,
    /// See `wait_state_cycles`.
    pub exception_cycles: u64,
    /// Share of the virtual time the core was busy (the rest it slept in WFI/WFE or was
    /// stalled by a flash operation), 0..1.
    pub cpu_load: f64,
    /// Share of the virtual time spent in the step interrupt (TIM5), entry included.
    pub step_irq_load: f64,
    /// Share of the virtual time spent in each interrupt handler (by IRQ name) and in
    /// thread mode ("thread"), where above 0.0001.
    pub load_by_context: BTreeMap<String, f64>,
    /// Virtual time, s.
    pub virtual_s: f64,
    /// Wall time, s.
    pub wall_s: f64,
    /// Instructions per wall second.
    pub instructions_per_s: f64,
    /// Virtual seconds per wall second.
    pub virtual_per_wall: f64,
    /// Cycles skipped in sleep, stalls and counter polling, s.
    pub skipped_s: f64,
    /// The USB side: what the emulated host found and did (when the cable was plugged).
    pub usb: Option<UsbReport>,
    /// `--serve`: the terminals, the lines on each port, the USB sessions, the pacing.
    pub serve: Option<ServeReport>,
    /// Notes from the models.
    pub notes: Vec<String>,
    /// Peripheral blocks the image touched that have no model (1 KiB block addresses).
    pub unmodelled: Vec<String>,
}

/// A name for exception number `e` (0: thread mode).
fn context_name(e: usize) -> String {
    let names = [
        (0, "thread"),
        (usize::from(exc::HARD_FAULT), "HardFault"),
        (usize::from(exc::SYSTICK), "SysTick"),
        (usize::from(exc::IRQ0 + irq::TIM2), "TIM2"),
        (usize::from(exc::IRQ0 + irq::TIM5), "TIM5"),
        (usize::from(exc::IRQ0 + irq::USART1), "USART1"),
        (usize::from(exc::IRQ0 + irq::SDIO), "SDIO"),
        (usize::from(exc::IRQ0 + irq::DMA2_STREAM3), "DMA2_STREAM3"),
        (usize::from(exc::IRQ0 + irq::OTG_FS), "OTG_FS"),
        (usize::from(exc::IRQ0 + irq::FLASH), "FLASH"),
    ];
    names
        .iter()
        .find(|(n, _)| *n == e)
        .map_or_else(|| format!("exception {e}"), |(_, s)| (*s).to_string())
}

/// The steps of the 3 s up to `parked` in time order, as runs of one kind: X and Y
/// together (travel), Z up or down, E forward or back — (start s, kind, net steps of each of
/// X Y Z E in the run).
fn park_moves(axes: &Axes, parked: Cyc) -> Vec<(f64, String, [i64; 4])> {
    let from = parked.saturating_sub(20 * CPU_HZ);
    let mut steps: Vec<(Cyc, usize, i8)> = Vec::new();
    for (i, a) in axes.axis.iter().enumerate() {
        steps.extend(
            a.rises
                .iter()
                .filter(|(t, _)| *t <= parked && *t >= from)
                .map(|(t, d)| (*t, i, *d)),
        );
    }
    steps.sort();
    let mut runs: Vec<(f64, String, [i64; 4])> = Vec::new();
    for (t, i, d) in steps {
        let kind = match (i, d) {
            (0 | 1, _) => "XY".to_string(),
            (_, 1) => format!("{}+", AXES[i]),
            _ => format!("{}-", AXES[i]),
        };
        match runs.last_mut() {
            Some(r) if r.1 == kind => r.2[i] += i64::from(d),
            _ => {
                let mut n = [0; 4];
                n[i] = i64::from(d);
                runs.push((s_from_cyc(t), kind, n));
            }
        }
    }
    if runs.len() > 40 {
        runs.drain(..runs.len() - 40);
    }
    runs
}

/// When the park began: the time of its first step (see [`pause_point`]).
fn park_began(axes: &Axes, parked: Cyc) -> Option<Cyc> {
    walk_back(axes, parked).map(|(_, t)| t)
}

/// Where the park began: walking back from the parked moment over the park's moves (XY
/// travel, then the Z lift, then the E retract, as `docs/pause.md` describes the park).
fn pause_point(axes: &Axes, parked: Cyc) -> Option<[i64; 4]> {
    walk_back(axes, parked).map(|(p, _)| p)
}

/// The walk back of [`pause_point`]: the position and the time of the park's first step.
fn walk_back(axes: &Axes, parked: Cyc) -> Option<([i64; 4], Cyc)> {
    let mut steps: Vec<(Cyc, usize, i8)> = Vec::new();
    for (i, a) in axes.axis.iter().enumerate() {
        steps.extend(
            a.rises
                .iter()
                .filter(|(t, _)| *t <= parked)
                .map(|(t, d)| (*t, i, *d)),
        );
    }
    steps.sort();
    let mut pos: [i64; 4] = [0, 1, 2, 3].map(|i| {
        axes.axis[i]
            .rises
            .iter()
            .filter(|(t, _)| *t <= parked)
            .map(|(_, d)| i64::from(*d))
            .sum()
    });
    let mut phase = 0;
    let mut began = parked;
    for &(t, i, d) in steps.iter().rev() {
        let next = match (i, d) {
            (0 | 1, _) if phase == 0 => 0,
            (2, 1) if phase <= 1 => 1,
            (3, -1) if phase <= 2 => 2,
            _ => break,
        };
        phase = next;
        pos[i] -= i64::from(d);
        began = t;
    }
    Some((pos, began))
}

/// What the run knew besides the board's state: how it was set up and when it saw what.
#[derive(Clone, Copy, Debug)]
pub struct RunFacts {
    /// Carriage start, mm from each switch (X, Y, Z).
    pub start_mm: [f32; 3],
    /// LSI frequency used, Hz.
    pub lsi_hz: u32,
    /// `//action:paused` seen at.
    pub parked: Option<Cyc>,
    /// M601 sent at.
    pub requested: Option<Cyc>,
    /// The job's first step.
    pub first_job_step: Option<Cyc>,
    /// A fault injected at.
    pub injected: Option<Cyc>,
    /// The stack's bounds (`_stack_end`, `_stack_start`).
    pub stack: Option<(u32, u32)>,
    /// Wall time of the run, s.
    pub wall_s: f64,
    /// The USB cable was plugged in (the report's `usb` part).
    pub usb_plugged: bool,
}

/// Builds the report; `lines` are those the host read, with their times.
pub fn make(emu: &Emulator, lines: &[(Cyc, String)], f: &RunFacts) -> Report {
    let RunFacts {
        start_mm,
        lsi_hz,
        parked,
        requested,
        first_job_step,
        injected,
        stack,
        wall_s,
        usb_plugged,
    } = *f;
    let b = emu.board();
    let now = emu.now();
    let timing = b.axes.timing();
    let cfg = firmware::config::MachineConfig::ENDER3;
    let axes_cfg = [
        firmware::motion::Axis::X,
        firmware::motion::Axis::Y,
        firmware::motion::Axis::Z,
        firmware::motion::Axis::E,
    ];
    // Schedule: every compare time armed, against the first step edge at or after it.
    let mut rises: Vec<Cyc> = b
        .axes
        .axis
        .iter()
        .flat_map(|a| a.rises.iter().map(|(t, _)| *t))
        .collect();
    rises.sort_unstable();
    let mut dev: Option<u64> = None;
    let mut matched = 0;
    let compares: Vec<Cyc> = b
        .tim5
        .ccr1_writes
        .iter()
        .map(|(_, m)| *m)
        .filter(|m| *m <= now)
        .collect();
    for &m in &compares {
        let i = rises.partition_point(|&t| t < m);
        if let Some(&t) = rises.get(i) {
            if t - m <= crate::time::cyc_from_us(50) {
                matched += 1;
                let d = ns_from_cyc(t - m);
                dev = Some(dev.map_or(d, |x| x.max(d)));
            }
        }
    }
    let after_fault = injected.map(|t0| {
        let safe = b
            .outputs_log
            .iter()
            .find(|(t, h, d)| *t >= t0 && !h.iter().any(|x| *x) && !d.iter().any(|x| *x))
            .map(|(t, _, _)| s_from_cyc(t - t0) * 1e3);
        let at = b
            .outputs_log
            .iter()
            .rev()
            .find(|(t, _, _)| *t <= t0)
            .map(|(_, h, _)| h.iter().any(|x| *x))
            .unwrap_or(false);
        // Already safe at the injection: 0.
        let safe = safe.or_else(|| {
            b.outputs_log
                .iter()
                .rev()
                .find(|(t, _, _)| *t <= t0)
                .filter(|(_, h, d)| !h.iter().any(|x| *x) && !d.iter().any(|x| *x))
                .map(|_| 0.0)
        });
        AfterFault {
            injected_s: s_from_cyc(t0),
            safe_after_ms: safe,
            heater_on_at_injection: at,
            reset_after_s: b
                .resets
                .iter()
                .find(|(t, _)| *t >= t0)
                .map(|(t, _)| s_from_cyc(t - t0)),
        }
    });
    let safe_power = crate::axes::SAFE_POWER;
    // The emulator's paint, or cortex-m-rt's `paint-stack` pattern: an image built with that
    // feature repaints its stack in the reset handler, over the emulator's.
    let stack_hw = stack.and_then(|(lo, hi)| {
        emu.lowest_touched(lo, hi, &[0xC5C5_C5C5, 0xCCCC_CCCC])
            .map(|a| hi - a)
    });
    let skipped = b.skipped;
    Report {
        m115: lines
            .iter()
            .find(|(_, l)| l.contains("FIRMWARE_NAME"))
            .map(|(_, l)| l.clone()),
        lines: lines.iter().map(|(_, l)| l.clone()).collect(),
        line_times_s: lines.iter().map(|(t, _)| s_from_cyc(*t)).collect(),
        net_steps: per_axis(|i| b.axes.axis[i].net_steps),
        pause_point_steps: parked.and_then(|t| pause_point(&b.axes, t)).map(|p| {
            // The firmware's frame: the switches are at 0 (min_mm of the Ender-3), and the
            // carriage started `start_mm` from them.
            let mut q = p;
            for (i, a) in [
                firmware::motion::Axis::X,
                firmware::motion::Axis::Y,
                firmware::motion::Axis::Z,
            ]
            .into_iter()
            .enumerate()
            {
                q[i] += (start_mm[i] * cfg.axis(a).steps_per_mm).round() as i64;
            }
            q
        }),
        pause_point_net_steps: parked.and_then(|t| pause_point(&b.axes, t)),
        pause_requested_s: requested.map(s_from_cyc),
        first_job_step_s: first_job_step.map(s_from_cyc),
        park_began_s: parked.and_then(|t| park_began(&b.axes, t)).map(s_from_cyc),
        parked_s: parked.map(s_from_cyc),
        park_moves: parked.map(|t| park_moves(&b.axes, t)).unwrap_or_default(),
        runs: per_axis(|i| b.axes.axis[i].runs.iter().take(12).copied().collect()),
        parked_steps: b
            .axes
            .marks
            .iter()
            .find(|(l, _, _)| l == "parked")
            .map(|(_, _, p)| *p),
        min_step_high_ns: per_axis(|i| timing[i].0),
        min_dir_setup_ns: per_axis(|i| timing[i].1),
        max_step_rate_hz: per_axis(|i| timing[i].2),
        step_rate_limit_hz: per_axis(|i| {
            let a = cfg.axis(axes_cfg[i]);
            f64::from(a.max_feed_mm_s * a.steps_per_mm)
        }),
        step_schedule_deviation_max_ns: dev,
        step_compares: (compares.len(), matched),
        stack_high_water_bytes: stack_hw,
        stack_size_bytes: stack.map(|(lo, hi)| hi - lo),
        watchdog_resets: b
            .resets
            .iter()
            .filter(|(_, k)| *k == ResetKind::Watchdog)
            .count(),
        resets: b
            .resets
            .iter()
            .skip(1)
            .map(|(t, k)| ResetEntry {
                t_s: s_from_cyc(*t),
                kind: *k,
            })
            .collect(),
        faults: emu
            .faults
            .iter()
            .map(|(t, w)| FaultEntry {
                t_s: s_from_cyc(*t),
                what: w.clone(),
            })
            .collect(),
        after_fault,
        heaters_powered_at_end: b.heaters_powered(),
        drivers_enabled_at_end: b.drivers_enabled(),
        safe_power_at_end: b.gpio.level(safe_power),
        safe_power_first_high_s: b.trace_first_high(safe_power).map(s_from_cyc),
        max_temp_c: b.heaters.max_c,
        flash_erases: b
            .flash
            .erases
            .iter()
            .map(|(t, n, d)| (s_from_cyc(*t), *n, s_from_cyc(*d)))
            .collect(),
        heaters_powered_during_erases: b.heaters_at_erase.clone(),
        watchdog_timeout_s: b.iwdg.timeout_s(),
        lsi_hz,
        sd_blocks_read: b.sdio.blocks_read,
        tmc_datagrams: [0, 1, 2, 3].map(|i| b.tmc.modules[i].datagrams),
        uart_overruns: b.usart1.overruns,
        instructions: b.insns,
        clock: b.clock.model,
        busy_cycles: b.cycles,
        cycles_per_instruction: b.cycles as f64 / (b.insns.max(1)) as f64,
        wait_state_cycles: b.clock.wait_cycles,
        literal_wait_cycles: b.clock.literal_wait_cycles,
        refill_cycles: b.clock.refill_cycles,
        exception_cycles: b.clock.exception_cycles,
        cpu_load: b.cycles as f64 / now.max(1) as f64,
        step_irq_load: b.busy_by_exc[usize::from(exc::IRQ0 + irq::TIM5)] as f64 / now.max(1) as f64,
        load_by_context: b
            .busy_by_exc
            .iter()
            .enumerate()
            .filter(|(_, &c)| c as f64 / now.max(1) as f64 > 1e-4)
            .map(|(e, &c)| (context_name(e), c as f64 / now.max(1) as f64))
            .collect(),
        virtual_s: s_from_cyc(now),
        wall_s,
        instructions_per_s: b.insns as f64 / wall_s.max(1e-9),
        virtual_per_wall: s_from_cyc(now) / wall_s.max(1e-9),
        skipped_s: skipped as f64 / CPU_HZ as f64,
        usb: usb_plugged.then(|| usb_report(b)),
        serve: None,
        notes: b.notes.iter().chain(&b.otg.notes).cloned().collect(),
        unmodelled: b.unmodelled.iter().map(|a| format!("{a:#010x}")).collect(),
    }
}
