//! The valid range of every setting, in one table: the command that sets a value at run time
//! (M92, M201, M203, M204, M205, M206, M301/M304, M760, M906) and the settings store that
//! saves and loads it (`storage::Settings::validate`) check it against the same [`Bound`], so
//! what runs can be saved and what loads could have been set (issue 24: `M204 S0.000001` was
//! taken at run time and refused by M500).
//!
//! Values that depend on the machine (the park position inside the travel, the park feed
//! within the X/Y limits) are checked against the machine as well
//! (`printer::guards::check_pause_params`, when set and when loaded).

/// The valid range of one kind of value, with its name and unit for messages.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    /// What the value is (for `echo:` messages).
    pub name: &'static str,
    /// Its unit.
    pub unit: &'static str,
    /// Smallest allowed value (besides 0 when [`Bound::zero_off`]).
    pub min: f32,
    /// Largest allowed value.
    pub max: f32,
    /// 0 is allowed too: it switches the feature off (M760 L0: no segmentation).
    pub zero_off: bool,
}

impl Bound {
    /// True when `v` is finite and within `min..=max` (or 0 where 0 means off).
    pub fn contains(&self, v: f32) -> bool {
        v.is_finite() && ((v >= self.min && v <= self.max) || (self.zero_off && v == 0.0))
    }

    const fn new(name: &'static str, unit: &'static str, min: f32, max: f32) -> Bound {
        Bound {
            name,
            unit,
            min,
            max,
            zero_off: false,
        }
    }
}

/// M92: steps per mm (0.1 to 10 000: keeps every position of the build volume in `i32` steps).
pub const STEPS_PER_MM: Bound = Bound::new("steps/mm", "steps/mm", 0.1, 10_000.0);
/// M203: an axis's maximum feed rate.
pub const MAX_FEED: Bound = Bound::new("max feed", "mm/s", 0.1, 2_000.0);
/// M201 and M204: accelerations.
pub const ACCEL: Bound = Bound::new("acceleration", "mm/s²", 1.0, 100_000.0);
/// M205 J: junction deviation, Marlin's range (`0.01 to 0.3`, `M205` in Marlin's
/// `gcode/config/M200-M205.cpp`).
pub const JUNCTION_DEVIATION: Bound = Bound::new("junction deviation", "mm", 0.01, 0.3);
/// M206: home offset of an axis.
pub const HOME_OFFSET: Bound = Bound::new("home offset", "mm", -1_000.0, 1_000.0);
/// M301/M304: a PID gain.
pub const PID_GAIN: Bound = Bound::new("PID gain", "", 0.0, 100_000.0);
/// M906: stepper driver RMS current (the SKR 2's TMC2209: up to 2 A RMS).
pub const DRIVER_CURRENT: Bound = Bound::new("driver current", "mA", 100.0, 2_000.0);
/// M760 R: the pause's retract.
pub const PAUSE_RETRACT: Bound = Bound::new("pause retract", "mm", 0.0, 20.0);
/// The pause's retract and un-retract feed (the configuration's; no M-code sets it).
pub const RETRACT_FEED: Bound = Bound::new("pause retract feed", "mm/s", 0.1, 1_000.0);
/// M760 Z: the pause's lift (also at most the Z travel of the machine).
pub const PAUSE_LIFT: Bound = Bound::new("pause lift", "mm", 0.0, 1_000.0);
/// M760 X Y: the park position (also inside the machine's travel).
pub const PARK_XY: Bound = Bound::new("park position", "mm", -1_000.0, 1_000.0);
/// M760 F: the park feed, mm/s (M760 gives it in mm/min; also at most the X/Y limits).
pub const PARK_FEED: Bound = Bound::new("park feed", "mm/s", 0.1, 2_000.0);
/// M760 S: the layer pause's speed-up.
pub const SPEEDUP: Bound = Bound::new("speed-up", "×", 1.0, 10.0);
/// M760 V: the extruder's volumetric flow limit during the speed-up.
pub const VOLUMETRIC: Bound = Bound::new("max flow", "mm³/s", 0.1, 1_000.0);
/// M760 T: the pause's nozzle timeout, s (0: off; at most a day). Not saved by M500.
pub const NOZZLE_TIMEOUT: Bound = Bound::new("nozzle timeout", "s", 0.0, 86_400.0);
/// M760 L: the planner's segment length (0: no segmentation; shorter than 0.05 mm would
/// flood the ring).
pub const SEGMENT: Bound = Bound {
    name: "segment length",
    unit: "mm",
    min: 0.05,
    max: 1_000.0,
    zero_off: true,
};
