//! Machine configuration in one place: build volume, steps per mm, speed and acceleration
//! limits, and the pause defaults. [`MachineConfig::ENDER3`] is the default profile (an
//! Ender-3-class Cartesian printer on a BigTreeTech SKR 2 with TMC2209 drivers at 16 microsteps).
//!
//! Runtime-changeable values (M204, M760, ...) live here too, so the firmware-specific M-codes
//! edit one struct; compile-time capacities (queue sizes) are constants next to the queue they
//! size.

use crate::motion::{Axis, AXES};

/// Limits and scale of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisConfig {
    /// Motor steps per millimetre of travel (filament length for E).
    pub steps_per_mm: f32,
    /// Highest speed of this axis alone, mm/s.
    pub max_feed_mm_s: f32,
    /// Highest acceleration of this axis alone, mm/s².
    pub max_accel_mm_s2: f32,
    /// Lowest allowed position in mm (software limit; ignored for E).
    pub min_mm: f32,
    /// Highest allowed position in mm (software limit; ignored for E).
    pub max_mm: f32,
}

/// Pause behaviour; defaults from SPEC §1, changed at run time by the firmware-specific M760.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PauseConfig {
    /// Filament retracted when the pause parks, mm (paper: 2 mm; slicers use 2–4 mm).
    pub retract_mm: f32,
    /// Speed of the retract and of the un-retract on resume, mm/s.
    pub retract_feed_mm_s: f32,
    /// Z lift above the pause point before parking, mm (clamped to the build volume).
    pub lift_z_mm: f32,
    /// Park position X, mm: the back corner, opposite the home corner, so the part can be seen.
    pub park_x_mm: f32,
    /// Park position Y, mm.
    pub park_y_mm: f32,
    /// Travel speed to and from the park position, mm/s (paper: F3600 = 60 mm/s).
    pub park_feed_mm_s: f32,
    /// Feed factor for the rest of the current layer after a `layer` request (paper: ×3);
    /// 1.0 disables the speed-up.
    pub speedup_factor: f32,
    /// Highest volumetric flow the extruder can melt, mm³/s: bounds the speed-up.
    pub max_volumetric_mm3_s: f32,
    /// Longest planner segment, mm: every move is cut into pieces no longer than this as it
    /// enters the queue, which bounds how far the head travels before a pause takes hold.
    pub segment_len_mm: f32,
}

/// Everything the portable firmware needs to know about the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MachineConfig {
    /// Per-axis scale and limits, indexed by [`Axis`].
    pub axes: [AxisConfig; AXES],
    /// Default acceleration of printing moves, mm/s² (M204 P).
    pub accel_print_mm_s2: f32,
    /// Default acceleration of travel moves, mm/s² (M204 T).
    pub accel_travel_mm_s2: f32,
    /// Acceleration of extruder-only moves (retract/prime), mm/s² (M204 R).
    pub accel_retract_mm_s2: f32,
    /// Junction deviation, mm: how far the path may deviate from a sharp corner taken at speed.
    pub junction_deviation_mm: f32,
    /// Filament diameter, mm (for volumetric flow limits).
    pub filament_diameter_mm: f32,
    /// Feed rate used before the job sets one, mm/s.
    pub default_feed_mm_s: f32,
    /// Pause defaults.
    pub pause: PauseConfig,
    /// Home offsets X Y Z, mm (M206): after G28 the logical position of a homed axis is its
    /// home position plus this (Marlin's `home_offset`).
    pub home_offset_mm: [f32; 3],
    /// Stepper driver RMS currents X Y Z E, mA (M906): the board's drivers apply them.
    pub driver_current_ma: [u16; AXES],
}

impl MachineConfig {
    /// Ender-3-class printer on an SKR 2: 235 × 235 × 250 mm, 80/80/400/93 steps/mm,
    /// Marlin's Ender-3 limits (500/500/5/25 mm/s, 500/500/100/5000 mm/s²).
    pub const ENDER3: MachineConfig = MachineConfig {
        axes: [
            AxisConfig {
                steps_per_mm: 80.0,
                max_feed_mm_s: 500.0,
                max_accel_mm_s2: 500.0,
                min_mm: 0.0,
                max_mm: 235.0,
            },
            AxisConfig {
                steps_per_mm: 80.0,
                max_feed_mm_s: 500.0,
                max_accel_mm_s2: 500.0,
                min_mm: 0.0,
                max_mm: 235.0,
            },
            AxisConfig {
                steps_per_mm: 400.0,
                max_feed_mm_s: 5.0,
                max_accel_mm_s2: 100.0,
                min_mm: 0.0,
                max_mm: 250.0,
            },
            AxisConfig {
                steps_per_mm: 93.0,
                max_feed_mm_s: 25.0,
                max_accel_mm_s2: 5000.0,
                min_mm: f32::NEG_INFINITY,
                max_mm: f32::INFINITY,
            },
        ],
        accel_print_mm_s2: 500.0,
        accel_travel_mm_s2: 500.0,
        accel_retract_mm_s2: 500.0,
        junction_deviation_mm: 0.013,
        filament_diameter_mm: 1.75,
        default_feed_mm_s: 25.0,
        pause: PauseConfig {
            retract_mm: 2.0,
            retract_feed_mm_s: 25.0,
            lift_z_mm: 5.0,
            park_x_mm: 235.0,
            park_y_mm: 235.0,
            park_feed_mm_s: 60.0,
            speedup_factor: 3.0,
            max_volumetric_mm3_s: 12.0,
            segment_len_mm: 0.2,
        },
        home_offset_mm: [0.0; 3],
        driver_current_ma: [crate::storage::DEFAULT_DRIVER_CURRENT_MA; AXES],
    };

    /// The configuration of one axis.
    pub fn axis(&self, axis: Axis) -> &AxisConfig {
        &self.axes[axis.index()]
    }
}

impl Default for MachineConfig {
    fn default() -> Self {
        Self::ENDER3
    }
}
