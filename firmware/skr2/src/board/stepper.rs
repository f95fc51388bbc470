//! Step generation on the board: the executive's step events (computed in the motion loop by
//! the portable step generator, a few milliseconds ahead) go through a lock-free
//! single-producer/single-consumer queue to the TIM5 compare interrupt, which runs at the
//! highest priority and only sets pins at the events' times:
//!
//! 1. DIR lines of the stepping axes that change, then the driver's direction setup time
//!    ([`DIR_SETUP_NS`]);
//! 2. STEP high on every stepping axis at once, the minimum pulse width ([`PULSE_NS`]), STEP low;
//! 3. the next event's time into CCR1, or the compare interrupt off when the queue is empty.
//!
//! Before firing, each event gets its earliest time from the re-timer
//! (`firmware::drivers::retime`): an event that comes late (the motion loop stalled longer
//! than the queue covers) shifts the rest of the schedule instead of firing in a burst, and no
//! axis ever steps sooner than its floor after its previous step (steps/mm × max feed, never
//! below [`MIN_STEP_PERIOD_NS`]). The motion loop keeps the floors in step with M92/M203
//! ([`floors`]) and reports the re-timed events ([`StepIsr::retime`]).
//!
//! The interrupt also keeps the position in steps and enforces the software limits of the
//! configured volume on homed axes (`drivers::StepExecutor`, in the executive's step frame);
//! axes not homed move as Marlin's default moves them, and G28's homing moves anywhere.
//! During a homing approach it reads the approach's endstop before each of its events and
//! stops at the switch (`firmware::drivers::homing_watch`): the events left are dropped and
//! counted, and the motion loop hands the count to the executive ([`take_trip`]).

use core::cell::RefCell;
use critical_section::Mutex;
use embassy_stm32::gpio::{Input, Output};
use embassy_stm32::interrupt::{self, InterruptExt, Priority};
use embassy_stm32::pac;
use heapless::spsc::{Consumer, Producer, Queue};

use super::clock;
use super::drivers::homing_watch::{EndstopWatch, EventFlags, Trip};
use super::drivers::retime::{axis_floor_ticks, RetimeConfig, Retimer};
use super::drivers::{StepExecutor, StepperPins};
use firmware::config::MachineConfig;
use firmware::homing::PinEndstops;
use firmware::motion::{Axis, AXES};

/// The X, Y, Z minimum endstops (PC1, PC3, PC0, pulled up).
pub type BoardEndstops = PinEndstops<Input<'static>, Input<'static>, Input<'static>>;

/// Events buffered ahead of the interrupt (each 16 B). At 100 k events/s this is 2.5 ms.
pub const QUEUE_LEN: usize = 256;
/// How far ahead of time the motion loop fills the queue, ns.
pub const LOOKAHEAD_NS: u64 = 2_000_000;
/// DIR setup before the step edge, ns (TMC2209: 20 ns; A4988: 200 ns; DRV8825: 650 ns).
pub const DIR_SETUP_NS: u32 = 650;
/// STEP high time, ns (TMC2209: 100 ns; A4988: 1 µs; DRV8825 needs 1.9 µs: raise it to 2000).
pub const PULSE_NS: u32 = 1_000;
/// The shortest time between two steps of one axis, ns: twice the STEP pulse, Marlin's
/// `MAXIMUM_STEPPER_RATE` rule (`1e6 / (2 × MINIMUM_STEPPER_PULSE)` steps/s,
/// `Conditionals_adv.h`).
pub const MIN_STEP_PERIOD_NS: u32 = 2 * PULSE_NS;
/// An event this much past its due time shifts the rest of the schedule, ns (smaller lateness
/// is interrupt latency and a few events due at once: fired without shifting).
pub const LATE_TOLERANCE_NS: u32 = 20_000;
/// How much of a step's lateness its axis's floor forgives, ns (`RetimeConfig::
/// latency_slack_ticks`): two steps of an axis come no closer than its limit's period less
/// this, three ticks of the time base (the floor rounded down, an event fired a tick early,
/// the clock read's resolution) and, after a direction change, the DIR setup — 1.25 µs
/// without one, 1.9 µs with it, however long a critical section held the interrupt back. 500 ns covers the interrupt's own entry (84 cycles at
/// 168 MHz, to its clock read), so on-time steps of an axis at its limit are not dragged.
pub const LATENCY_SLACK_NS: u32 = 500;
/// A planned gap this long between two events means every axis is at rest, ns: the
/// re-timer's shift may shrink there (20 ms: under 50 steps/s on any axis).
pub const REST_GAP_NS: u32 = 20_000_000;
/// CPU clock, Hz (for the busy-wait delays).
pub const CPU_HZ: u32 = 168_000_000;
/// Most events the interrupt executes in one entry before yielding (it runs with interrupts
/// masked: 8 events ≈ 25 µs, well inside a UART byte time at 115200 Bd).
const MAX_PER_IRQ: usize = 8;

/// One event as the interrupt sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PinEvent {
    /// When, in [`clock`] ticks.
    pub t_ticks: u64,
    /// Axes that step (bit i = axis i).
    pub axis_mask: u8,
    /// Directions (bit set = positive).
    pub dir_mask: u8,
    /// Homing move, and the switch that ends it.
    pub flags: EventFlags,
}

/// The interrupt's state.
pub struct StepIsr {
    /// Pins, position, limits (the portable part, `drivers::StepExecutor`).
    pub exec: StepExecutor<Output<'static>>,
    /// The endstops: watched during homing approaches, sampled by the motion loop for M119.
    pub endstops: BoardEndstops,
    /// The approach's switch, watched before each of its events.
    pub watch: EndstopWatch,
    /// Each event's earliest time: no burst after a stall, no axis above its limit.
    pub retime: Retimer,
    consumer: Consumer<'static, PinEvent>,
    /// Drop every queued event (halt / quick stop).
    pub flush: bool,
    /// True while the compare interrupt is armed.
    pub running: bool,
}

static QUEUE: static_cell::StaticCell<Queue<PinEvent, QUEUE_LEN>> = static_cell::StaticCell::new();
/// The interrupt's state, shared with the motion loop under a critical section.
pub static ISR: Mutex<RefCell<Option<StepIsr>>> = Mutex::new(RefCell::new(None));

/// Sets up the queue and the interrupt at `priority` (the highest of the image); returns the
/// producer side for the motion loop.
pub fn init(
    pins: StepperPins<Output<'static>>,
    endstops: BoardEndstops,
    priority: Priority,
) -> Producer<'static, PinEvent> {
    let (producer, consumer) = QUEUE.init(Queue::new()).split();
    critical_section::with(|cs| {
        ISR.borrow(cs).replace(Some(StepIsr {
            exec: StepExecutor::new(pins),
            endstops,
            watch: EndstopWatch::new(),
            retime: Retimer::new(floors(&MachineConfig::ENDER3)),
            consumer,
            flush: false,
            running: false,
        }))
    });
    interrupt::TIM5.set_priority(priority);
    // SAFETY: the handler below only touches state behind the critical-section mutex.
    unsafe { interrupt::TIM5.enable() };
    producer
}

/// Wakes the interrupt after events were queued (it arms the compare itself).
pub fn kick() {
    interrupt::TIM5.pend();
}

/// CPU cycles for `ns` nanoseconds (busy-wait delays).
pub fn cycles(ns: u32) -> u32 {
    (ns as u64 * CPU_HZ as u64 / 1_000_000_000) as u32
}

fn ticks(ns: u32) -> u32 {
    ns.div_ceil(clock::NS_PER_TICK as u32)
}

/// The re-timer's limits for `cfg`: each axis's floor from its steps/mm and max feed (M92,
/// M203), never below [`MIN_STEP_PERIOD_NS`].
pub fn floors(cfg: &MachineConfig) -> RetimeConfig {
    let min_step = ticks(MIN_STEP_PERIOD_NS);
    let mut min_period_ticks = [min_step; AXES];
    for (axis, p) in Axis::ALL.into_iter().zip(min_period_ticks.iter_mut()) {
        let a = cfg.axis(axis);
        *p = axis_floor_ticks(a.steps_per_mm, a.max_feed_mm_s, clock::TICK_HZ, min_step);
    }
    RetimeConfig {
        min_period_ticks,
        min_step_ticks: min_step,
        latency_slack_ticks: ticks(LATENCY_SLACK_NS),
        late_tolerance_ticks: ticks(LATE_TOLERANCE_NS),
        rest_gap_ticks: ticks(REST_GAP_NS),
    }
}

impl StepIsr {
    fn run(&mut self, cs: critical_section::CriticalSection) {
        let tim = pac::TIM5;
        tim.sr().modify(|w| w.set_ccif(0, false));
        if self.flush {
            while self.consumer.dequeue().is_some() {}
            self.flush = false;
            self.retime.restart();
        }
        for _ in 0..MAX_PER_IRQ {
            let Some(ev) = self.consumer.peek().copied() else {
                tim.dier().modify(|w| w.set_ccie(0, false));
                self.running = false;
                return;
            };
            let due = self.retime.due(ev.t_ticks, ev.axis_mask);
            let now = clock::now_ticks_cs(cs);
            if due > now + 1 {
                // Arm the compare for the event; if the counter passed it meanwhile, loop.
                tim.ccr(0).write_value(due as u32);
                tim.dier().modify(|w| w.set_ccie(0, true));
                self.running = true;
                if clock::now_ticks_cs(cs) < due {
                    return;
                }
                continue;
            }
            let _ = self.consumer.dequeue();
            if !self
                .watch
                .admit(ev.flags, ev.axis_mask, ev.dir_mask, &mut self.endstops)
            {
                // Stopped at the switch: drop (and count) the rest of the approach at once.
                self.drop_queued();
                continue;
            }
            let delay = |ns| cortex_m::asm::delay(cycles(ns));
            let stepped = if ev.flags.homing() {
                self.exec
                    .fire_homing(ev.axis_mask, ev.dir_mask, DIR_SETUP_NS, PULSE_NS, delay)
            } else {
                self.exec
                    .fire(ev.axis_mask, ev.dir_mask, DIR_SETUP_NS, PULSE_NS, delay)
            };
            self.retime.fired(stepped, now);
        }
        // Many events due at once (catching up): come back right away.
        interrupt::TIM5.pend();
    }
}

impl StepIsr {
    /// Drops every queued event into the pending trip's count.
    fn drop_queued(&mut self) {
        while let Some(ev) = self.consumer.dequeue() {
            let _ = self
                .watch
                .admit(ev.flags, ev.axis_mask, ev.dir_mask, &mut self.endstops);
        }
    }

    /// Events are still queued or running.
    pub fn in_flight(&self) -> bool {
        self.running || self.consumer.ready() || self.watch.tripped()
    }
}

/// The pending endstop trip, if an approach stopped at its switch, with every event still
/// queued counted in it (the queue is then empty).
pub fn take_trip() -> Option<Trip> {
    with(|s| {
        if !s.watch.tripped() {
            return None;
        }
        s.drop_queued();
        s.watch.take()
    })
    .flatten()
}

#[embassy_stm32::interrupt]
fn TIM5() {
    critical_section::with(|cs| {
        if let Some(isr) = ISR.borrow(cs).borrow_mut().as_mut() {
            isr.run(cs);
        }
    });
}

/// Runs `f` on the interrupt's state (the motion loop and homing use this).
pub fn with<R>(f: impl FnOnce(&mut StepIsr) -> R) -> Option<R> {
    critical_section::with(|cs| ISR.borrow(cs).borrow_mut().as_mut().map(f))
}
