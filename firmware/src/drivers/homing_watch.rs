//! The endstop watch of a step interrupt that runs step events queued ahead of time (the
//! board queues up to 2 ms of them): during a homing approach the interrupt reads the
//! approach's switch before each of the approach's events, as Marlin's stepper ISR checks its
//! endstops, and when the switch is pressed it takes no more steps: that event and every event
//! still queued are dropped and counted ([`Trip::undone`]). The motion loop takes the trip
//! ([`EndstopWatch::take`]) and hands it to `Printer::endstop_trip`, which ends
//! the move and moves the executive's position back by what was never taken.
//!
//! Each queued event carries [`EventFlags`]: whether it belongs to a homing move (allowed
//! before the axes are homed, and outside the software limits: the raise of Z and the
//! approaches start from an unknown position) and which switch ends it.

use crate::homing::Endstops;
use crate::motion::{Axis, AXES};
use crate::planner::BlockKind;
use crate::stepgen::StepEvent;

/// Per-event flags of the board's step queue (one byte).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EventFlags(pub u8);

impl EventFlags {
    /// A homing move: allowed on axes not homed yet, outside the software limits.
    pub const HOMING: u8 = 1 << 7;

    /// The flags of `ev`; `watch` is the executive's `Printer::homing_watch()` mask, read
    /// right after `Printer::next_step` (the homing move cannot change in between).
    pub fn of(watch: u8, ev: &StepEvent) -> Self {
        if ev.kind == BlockKind::Homing {
            EventFlags(Self::HOMING | (watch & 0b111))
        } else {
            EventFlags(0)
        }
    }

    /// The event belongs to a homing move.
    #[inline(always)]
    pub fn homing(self) -> bool {
        self.0 & Self::HOMING != 0
    }

    /// The axis whose switch ends the event's move, if any.
    #[inline(always)]
    pub fn watch(self) -> Option<Axis> {
        match self.0 & 0b111 {
            0 => None,
            w if w & 1 != 0 => Some(Axis::X),
            w if w & 2 != 0 => Some(Axis::Y),
            _ => Some(Axis::Z),
        }
    }
}

/// An approach stopped by its switch.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trip {
    /// The axis whose switch triggered.
    pub axis: Axis,
    /// Steps per axis (signed) of the events dropped: generated, never taken.
    pub undone: [i32; AXES],
}

impl Trip {
    /// Count one dropped event.
    pub fn add(&mut self, axis_mask: u8, dir_mask: u8) {
        for (i, u) in self.undone.iter_mut().enumerate() {
            if axis_mask & (1 << i) != 0 {
                *u += if dir_mask & (1 << i) != 0 { 1 } else { -1 };
            }
        }
    }
}

/// The interrupt's side. See the module documentation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EndstopWatch {
    trip: Option<Trip>,
}

impl EndstopWatch {
    /// No trip.
    pub const fn new() -> Self {
        EndstopWatch { trip: None }
    }

    /// Whether the due event (`flags`, `axis_mask`, `dir_mask`) may step. False when its
    /// approach's switch is pressed now, or a trip is pending (every event is then dropped and
    /// counted until the motion loop takes the trip).
    #[inline(always)]
    pub fn admit(
        &mut self,
        flags: EventFlags,
        axis_mask: u8,
        dir_mask: u8,
        endstops: &mut impl Endstops,
    ) -> bool {
        if self.trip.is_none() {
            let Some(axis) = flags.watch() else {
                return true;
            };
            if !endstops.triggered(axis) {
                return true;
            }
            self.trip = Some(Trip {
                axis,
                undone: [0; AXES],
            });
        }
        if let Some(t) = self.trip.as_mut() {
            t.add(axis_mask, dir_mask);
        }
        false
    }

    /// A trip is pending.
    pub fn tripped(&self) -> bool {
        self.trip.is_some()
    }

    /// Take the pending trip (the motion loop); events flow again.
    pub fn take(&mut self) -> Option<Trip> {
        self.trip.take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Pressed(u8);
    impl Endstops for Pressed {
        fn triggered(&mut self, axis: Axis) -> bool {
            self.0 & (1 << axis.index()) != 0
        }
    }

    #[test]
    fn flags_name_the_watched_axis() {
        assert_eq!(EventFlags(0).watch(), None);
        assert!(!EventFlags(0).homing());
        let f = EventFlags(EventFlags::HOMING | 0b100);
        assert!(f.homing());
        assert_eq!(f.watch(), Some(Axis::Z));
        assert_eq!(
            EventFlags(EventFlags::HOMING | 0b010).watch(),
            Some(Axis::Y)
        );
        assert_eq!(EventFlags(0b001).watch(), Some(Axis::X));
    }

    #[test]
    fn a_pressed_switch_drops_and_counts_everything_until_taken() {
        let mut w = EndstopWatch::new();
        let approach_x = EventFlags(EventFlags::HOMING | 1);
        let mut open = Pressed(0);
        let mut x = Pressed(1);
        // Unwatched events step whatever the switches say.
        assert!(w.admit(EventFlags(0), 0b1, 0, &mut x));
        assert!(w.admit(approach_x, 0b1, 0, &mut open));
        assert!(!w.tripped());
        // The switch closes: this event and the rest are dropped and counted.
        assert!(!w.admit(approach_x, 0b1, 0, &mut x));
        assert!(!w.admit(approach_x, 0b1, 0, &mut open));
        assert!(!w.admit(EventFlags(0), 0b1001, 0b1000, &mut open));
        let t = w.take().expect("tripped");
        assert_eq!(t.axis, Axis::X);
        assert_eq!(t.undone, [-3, 0, 0, 1]);
        assert!(w.take().is_none());
        assert!(w.admit(EventFlags(0), 0b1, 0, &mut x));
    }
}
