//! The motion task (every 1 ms), the executive's one owner: the other tasks' messages in
//! (host bytes, sessions, temperatures: `channels`), the pause button, G28 through the step
//! interrupt, the executive's poll, step events into the step interrupt's queue, stepper
//! enable/disable and idle timeout, halt handling, the answers and heater duties out; the
//! flash store and the card served in turn, and the drivers while nothing moves.

use embassy_stm32::gpio::Input;
use embassy_time::{Duration, Ticker};
use firmware::printer::{Printer, State, StepperRequest};
use firmware::stepgen::StepEvent;
use heapless::spsc::Producer;

use super::drivers::{service_drivers, Drivers};
use super::heater::serve_heaters;
use super::host::{flush_output, output_waiting, take_input, take_sessions, Carry};
use super::{beat, printer_now_ns, printer_now_us, LOOP_MOTION};
use crate::board::clock;
use crate::board::drivers::homing_watch::EventFlags;
use crate::board::drivers::retime::RetimeStats;
use crate::board::drivers::{IdleTimeout, PauseButton};
use crate::board::flash::{self, serve_store, Store};
use crate::board::sd::{self, serve_card, SdioCard};
use crate::board::stack;
use crate::board::stepper::{self, PinEvent, LOOKAHEAD_NS};
use firmware::printer::BoardStats;
use firmware::storage::sd::Card;

/// Stepper drivers switch off after this long without motion (Marlin's default 120 s).
const STEPPER_IDLE_S: u32 = 120;

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
        let flags = EventFlags::of(p.homing_watch(), &ev);
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

/// How often the board's measurements (stack high-water mark, re-timed steps) are refreshed
/// for M115, and new late steps reported, ms.
const STATS_MS: u32 = 1_000;

/// Refreshes the board's measurements in the executive (M115 reports them) and the step
/// interrupt's floors (M92/M203 may have changed them); says on every port when step events
/// came late since the last report (each one shifted the schedule instead of bursting).
fn board_stats(p: &mut Printer, reported: &mut RetimeStats) {
    let floors = stepper::floors(p.config());
    let s = stepper::with(|s| {
        if s.retime.config() != floors {
            s.retime.set_config(floors);
        }
        s.retime.stats()
    })
    .unwrap_or_default();
    let (used, size) = stack::high_water();
    let us = |ticks: u64| (ticks * clock::NS_PER_TICK / 1000).min(u64::from(u32::MAX)) as u32;
    p.set_board_stats(BoardStats {
        stack_used_bytes: used,
        stack_size_bytes: size,
        steps_late: s.late,
        steps_capped: s.capped,
        worst_late_us: us(s.worst_late_ticks),
    });
    if s.late > reported.late {
        let mut t: heapless::String<160> = heapless::String::new();
        let _ = core::fmt::Write::write_fmt(
            &mut t,
            format_args!(
                "step timing: {} step events came late after a stall (worst {} us): re-timed, \
                 no axis faster than planned",
                s.late - reported.late,
                us(s.worst_late_ticks)
            ),
        );
        defmt::warn!("{}", t.as_str());
        p.board_notice(&t);
    }
    *reported = s;
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

/// The step interrupt follows the executive's configuration: its floors at once after any
/// change (M92, M203: `board_stats` alone took them once a second, and a fast move after
/// `M92 X10000` ran on the old floors), its frame (position and travel limits in the current
/// steps per mm, after M92/M350) once its queue has run dry — events of the old frame must not
/// meet the new limits. Returns false while a new frame waits for the queue to empty (no new
/// events are queued meanwhile: they belong to the new frame).
fn follow_config(
    p: &Printer,
    config_epoch: &mut Option<u32>,
    held: &Option<(StepEvent, EventFlags)>,
) -> bool {
    if *config_epoch != Some(p.config_epoch()) {
        *config_epoch = Some(p.config_epoch());
        let floors = stepper::floors(p.config());
        stepper::with(|s| s.retime.set_config(floors));
    }
    let frame = p.travel_frame();
    stepper::with(|s| {
        if s.exec.frame_epoch() == frame.epoch {
            return true;
        }
        if s.running || held.is_some() {
            return false;
        }
        s.exec.follow(&frame);
        true
    })
    .unwrap_or(true)
}

/// After `Printer::poll`, before new events are queued: the step interrupt follows the
/// executive's homed axes (an axis homed in this poll is at its minimum).
fn homing_after_poll(p: &mut Printer) {
    let fresh = p.take_homed();
    let homed = p.homed_axes();
    let home = p.config().travel_limits_steps().map(|(min, _)| min);
    stepper::with(|s| s.exec.set_homed(homed, fresh, home));
}

/// What the other tasks sent the executive since the last tick: sessions, host bytes (as far
/// as it takes them), temperatures (answered with the heaters' duties).
fn messages_in(p: &mut Printer, carry: &mut [Carry; 2]) {
    take_sessions(p);
    take_input(p, carry);
    serve_heaters(p);
}

/// How long the host link must have been quiet before a flash operation, ms: a sector erase
/// stalls the core for up to 2 s (code runs from flash), so what the executive just said
/// (`//action:paused` before the record it keeps) reaches the host first — the TFT UART's
/// 512-byte transmit buffer empties in 44 ms at 115200 Bd.
const HOST_TOLD_MS: u32 = 50;
/// Longest a pending store operation waits for that quiet, ms (a host that keeps the link
/// busy does not hold a record back).
const STORE_WAIT_MAX_MS: u32 = 1_000;

/// The executive's devices besides motion, served by the motion task in turn.
pub(super) struct Devices {
    /// The settings store (none if its area was misconfigured).
    pub(super) store: Option<Store>,
    /// The micro-SD card.
    pub(super) card: Card<SdioCard>,
    /// The last tick that had host output on its way.
    pub(super) out_tick: u32,
    /// Since when a store operation is pending.
    pub(super) pending_since: Option<u32>,
}

impl Devices {
    /// The card every [`sd::POLL_MS`] ticks; the store every [`flash::POLL_MS`] once the host
    /// has been told what the executive said ([`HOST_TOLD_MS`], at most [`STORE_WAIT_MAX_MS`]).
    fn serve(&mut self, p: &mut Printer, tick: u32, wrote: bool) {
        if tick.is_multiple_of(sd::POLL_MS) {
            serve_card(p, &mut self.card, printer_now_us());
        }
        if wrote || output_waiting() {
            self.out_tick = tick;
        }
        self.pending_since = match (p.store_request_pending(), self.pending_since) {
            (false, _) => None,
            (true, None) => Some(tick),
            (true, since) => since,
        };
        let told = tick.wrapping_sub(self.out_tick) >= HOST_TOLD_MS;
        let overdue = self
            .pending_since
            .is_some_and(|t| tick.wrapping_sub(t) >= STORE_WAIT_MAX_MS);
        if !tick.is_multiple_of(flash::POLL_MS) || !(told || overdue) {
            return;
        }
        if let Some(store) = self.store.as_mut() {
            serve_store(p, store);
        }
    }
}

#[embassy_executor::task]
pub(super) async fn motion_task(
    p: &'static mut Printer,
    mut devices: Devices,
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
    let mut reported = RetimeStats::default();
    let mut config_epoch = None;
    let mut carry = [Carry::new(), Carry::new()];
    loop {
        ticker.next().await;
        beat(LOOP_MOTION);
        messages_in(p, &mut carry);
        if blink.is_multiple_of(STATS_MS) {
            board_stats(p, &mut reported);
        }
        let now_us = printer_now_us();
        let wrote;
        {
            let state = p.state();
            let paused = matches!(state, State::Paused | State::Pausing);
            if let Some(req) = button.update(button_pin.is_low(), now_us, paused) {
                defmt::info!("pause button: {}", defmt::Debug2Format(&req));
                p.request(req, now_us);
            }
            homing_before_poll(p, &mut held);
            p.poll(now_us);
            homing_after_poll(p);
            let frame_ready = follow_config(p, &mut config_epoch, &held);
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
            } else if frame_ready {
                feed_steps(p, &mut producer, &mut held);
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
                    // The executive checked every target: a refusal here is a fault of the
                    // firmware, told to the hosts (its moves did not all happen).
                    defmt::warn!("{} steps refused outside the travel limits", n);
                    let mut t: heapless::String<120> = heapless::String::new();
                    let _ = core::fmt::Write::write_fmt(
                        &mut t,
                        format_args!(
                            "step interrupt: {n} steps refused outside the travel limits (a \
                             firmware fault: the position is no longer true)"
                        ),
                    );
                    p.board_notice(&t);
                }
            }
            wrote = flush_output(p);
        }
        devices.serve(p, blink, wrote);
        // The drivers' UART lines block the executor: only while nothing moves or is queued.
        let quiet = p.state() == State::Idle
            && p.next_step_ns().is_none()
            && !stepper::with(|s| s.running).unwrap_or(false);
        if quiet && !halted {
            service_drivers(p, &mut drivers);
        }
        blink = blink.wrapping_add(1);
        let period = if halted { 100 } else { 500 };
        if blink.is_multiple_of(period) {
            led.toggle();
        }
    }
}

/// The motion loop of a printer halted before its drivers got power (a driver module plugged
/// in backwards): no step interrupt, no drivers; the executive still answers (every line is
/// refused: halted), its output reaches both ports, the watchdog is fed, the LED blinks fast.
#[embassy_executor::task]
pub(super) async fn halted_task(
    p: &'static mut Printer,
    mut led: embassy_stm32::gpio::Output<'static>,
) {
    let mut ticker = Ticker::every(Duration::from_millis(1));
    let mut blink: u32 = 0;
    let mut reported = RetimeStats::default();
    let mut carry = [Carry::new(), Carry::new()];
    loop {
        ticker.next().await;
        beat(LOOP_MOTION);
        messages_in(p, &mut carry);
        p.poll(printer_now_us());
        if blink.is_multiple_of(STATS_MS) {
            board_stats(p, &mut reported);
        }
        flush_output(p);
        blink = blink.wrapping_add(1);
        if blink.is_multiple_of(100) {
            led.toggle();
        }
    }
}
