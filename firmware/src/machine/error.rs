//! Why the machine state refused a command (the state is then unchanged), with the message
//! the executive reports.

use crate::motion::Axis;
use core::fmt;

/// Why a command was refused. The state is unchanged whenever one of these is returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MachineError {
    /// The target lies outside the build volume (the axes' `min_mm..=max_mm`).
    OutOfBounds(Axis),
    /// The target in steps does not fit an `i32`.
    StepOverflow(Axis),
    /// `F` is zero or negative.
    BadFeed,
    /// `F` is below [`MIN_FEED_MM_MIN`](super::MIN_FEED_MM_MIN).
    FeedTooLow,
    /// M220/M221 outside [`OVERRIDE_RANGE_PCT`](super::OVERRIDE_RANGE_PCT).
    OverrideOutOfRange,
    /// G4/M0 with a negative time.
    NegativeTime,
    /// G2/G3 without I/J or R.
    ArcNoCentre,
    /// G2/G3 with both I/J and R.
    ArcCentreAndRadius,
    /// G2/G3 with R and the end point equal to the start point, or a zero radius.
    ArcDegenerate,
    /// A point of the arc between its start and end lies outside the build volume.
    ArcOutOfBounds(Axis),
    /// G2/G3 whose end point is not on the circle (radius mismatch beyond tolerance) or whose R
    /// is shorter than half the chord.
    ArcEndNotOnCircle,
}

impl MachineError {
    /// A short, static, human-readable description.
    pub const fn message(self) -> &'static str {
        match self {
            Self::OutOfBounds(_) => "move outside the build volume",
            Self::StepOverflow(_) => "position too large for the step counter",
            Self::BadFeed => "feed rate must be positive",
            Self::FeedTooLow => "feed rate below 6 mm/min",
            Self::OverrideOutOfRange => "override must be 10..999 percent",
            Self::NegativeTime => "time must not be negative",
            Self::ArcNoCentre => "arc needs I/J or R",
            Self::ArcCentreAndRadius => "arc takes either I/J or R, not both",
            Self::ArcDegenerate => "arc has no extent (zero radius, or R with end = start)",
            Self::ArcEndNotOnCircle => "arc end point is not on the circle",
            Self::ArcOutOfBounds(_) => "arc leaves the build volume",
        }
    }

    /// The axis concerned, if any.
    pub const fn axis(self) -> Option<Axis> {
        match self {
            Self::OutOfBounds(a) | Self::ArcOutOfBounds(a) | Self::StepOverflow(a) => Some(a),
            _ => None,
        }
    }
}

impl fmt::Display for MachineError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())?;
        if let Some(a) = self.axis() {
            write!(f, " ({})", a.letter())?;
        }
        Ok(())
    }
}
