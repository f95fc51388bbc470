//! Machine configuration in one place: build volume, steps per mm, microsteps, directions,
//! endstops, speed and acceleration limits, and the pause defaults. [`MachineConfig::ENDER3`] is
//! the default profile (an Ender-3-class Cartesian printer on a BigTreeTech SKR 2 with TMC2209
//! drivers at 16 microsteps).
//!
//! Sources of the defaults, cited per value below:
//! * [E3] MarlinFirmware/Configurations, the Ender-3 examples on TMC drivers:
//!   `config/examples/Creality/Ender-3/BigTreeTech SKR Mini E3 2.0/Configuration.h` (TMC2209)
//!   and `.../Ender-3/BigTreeTech SKR 1.4/Configuration.h` (TMC2208), which agree on every value
//!   used here;
//! * [CR] the same repository's SKR 2 example, `config/examples/Creality/CR-10S/BigTreeTech SKR
//!   2.0 TMC2209/Configuration.h` (`MOTHERBOARD BOARD_BTT_SKR_V2_0_REV_B`): the only SKR 2 +
//!   Creality example there (the Configurations repository has no SKR 2 + Ender-3 one);
//! * [K] Klipper, `config/generic-bigtreetech-skr-2.cfg`.
//!
//! Runtime-changeable values (M204, M760, ...) live here too, so the firmware-specific M-codes
//! edit one struct; compile-time capacities (queue sizes) are constants next to the queue they
//! size.

use crate::motion::{Axis, AXES};

/// Where an axis's endstop switch sits and how it reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Endstop {
    /// No endstop (the extruder).
    None,
    /// A switch at the minimum end of travel, on a pulled-up input.
    Min {
        /// The input reads high when the switch is hit (Marlin's `*_MIN_ENDSTOP_HIT_STATE
        /// HIGH`: a switch that holds the line to ground until pressed).
        hit_high: bool,
    },
}

/// Limits and scale of one axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisConfig {
    /// Motor steps per millimetre of travel (filament length for E), at [`Self::microsteps`].
    pub steps_per_mm: f32,
    /// Microsteps per full step the driver is set to (TMC2209 `CHOPCONF.MRES`, over UART).
    /// Changing it scales `steps_per_mm` in proportion (see [`MachineConfig::set_microsteps`]).
    pub microsteps: u16,
    /// DIR low moves the axis in the positive direction (Marlin's `INVERT_*_DIR true`).
    pub invert_dir: bool,
    /// The axis's endstop.
    pub endstop: Endstop,
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
    /// The corner speed is `v² = a · jd · sin(θ/2) / (1 − sin(θ/2))` (Marlin's
    /// `planner.cpp`), θ the angle between the moves' directions.
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
    /// stealthChop (true) or spreadCycle per driver X Y Z E (M569).
    pub driver_stealthchop: [bool; AXES],
}

impl MachineConfig {
    /// The software limits of X, Y, Z in steps at the current steps per mm (each of
    /// `min_mm`, `max_mm` times `steps_per_mm`, rounded to the nearest step).
    pub fn travel_limits_steps(&self) -> [(i32, i32); 3] {
        let steps = |i: usize, mm: f32| {
            let v = libm::roundf(mm * self.axes[i].steps_per_mm);
            if v.is_finite() {
                v.clamp(i32::MIN as f32, i32::MAX as f32) as i32
            } else {
                0
            }
        };
        [0, 1, 2].map(|i| (steps(i, self.axes[i].min_mm), steps(i, self.axes[i].max_mm)))
    }

    /// Ender-3-class printer on an SKR 2 with TMC2209 drivers over UART.
    ///
    /// * Volume 235 × 235 × 250 mm ([E3] `X_BED_SIZE 235`, `Y_BED_SIZE 235`, `Z_MAX_POS 250`).
    /// * Steps/mm 80/80/400/93 at 16 microsteps ([E3] `DEFAULT_AXIS_STEPS_PER_UNIT { 80, 80,
    ///   400, 93 }`; 20-tooth GT2 pulleys: 200 × 16 / 40 mm = 80; Z leadscrew 8 mm/turn: 400; the
    ///   stock extruder 93; [K] `microsteps: 16`, `rotation_distance: 40`).
    /// * Directions: X, Y and E0 inverted, Z not ([E3] and [CR] `INVERT_X_DIR true`,
    ///   `INVERT_Y_DIR true`, `INVERT_Z_DIR false`, `INVERT_E0_DIR true`; a TMC driver turns the
    ///   motor the other way from the A4988 of the stock Creality board, whose example
    ///   `Ender-3/CrealityV422` has X, Y, E0 not inverted and Z inverted).
    /// * Endstops at the minimum of X, Y, Z, hit = high on a pulled-up input ([E3]
    ///   `ENDSTOPPULLUPS`, `X/Y/Z_MIN_ENDSTOP_HIT_STATE HIGH`; [K] `endstop_pin: ^PC1`, `^PC3`,
    ///   `^PC0`, not inverted).
    /// * Limits 500/500/5/25 mm/s, 500/500/100/5000 mm/s², accelerations 500 ([E3]
    ///   `DEFAULT_MAX_FEEDRATE`, `DEFAULT_MAX_ACCELERATION`, `DEFAULT_ACCELERATION`,
    ///   `DEFAULT_RETRACT_ACCELERATION`, `DEFAULT_TRAVEL_ACCELERATION`).
    /// * TMC2209 at 580/580/580/650 mA RMS, hold at half, Rsense 0.11 Ω, stealthChop on every
    ///   axis ([E3] SKR Mini E3 2.0 `Configuration_adv.h`: `X_CURRENT 580`, `Y_CURRENT 580`,
    ///   `Z_CURRENT 580`, `E0_CURRENT 650`, `*_RSENSE 0.11`, `HOLD_MULTIPLIER 0.5`,
    ///   `STEALTHCHOP_XY`, `STEALTHCHOP_Z`, `STEALTHCHOP_E`, `HYBRID_THRESHOLD` off).
    /// * Junction deviation 0.08 mm ([E3] `JUNCTION_DEVIATION_MM 0.08`, `CLASSIC_JERK` off):
    ///   at 500 mm/s² a 90° corner is taken at √(500 · 0.08 · 2.414) ≈ 9.8 mm/s, about the
    ///   10 mm/s `DEFAULT_XJERK` of the same files. Marlin's generic default 0.013 (this firmware's
    ///   earlier value) gives ≈ 4 mm/s there: every corner of a print slowed to a crawl.
    pub const ENDER3: MachineConfig = MachineConfig {
        axes: [
            AxisConfig {
                steps_per_mm: 80.0,
                microsteps: 16,
                invert_dir: true,
                endstop: Endstop::Min { hit_high: true },
                max_feed_mm_s: 500.0,
                max_accel_mm_s2: 500.0,
                min_mm: 0.0,
                max_mm: 235.0,
            },
            AxisConfig {
                steps_per_mm: 80.0,
                microsteps: 16,
                invert_dir: true,
                endstop: Endstop::Min { hit_high: true },
                max_feed_mm_s: 500.0,
                max_accel_mm_s2: 500.0,
                min_mm: 0.0,
                max_mm: 235.0,
            },
            AxisConfig {
                steps_per_mm: 400.0,
                microsteps: 16,
                invert_dir: false,
                endstop: Endstop::Min { hit_high: true },
                max_feed_mm_s: 5.0,
                max_accel_mm_s2: 100.0,
                min_mm: 0.0,
                max_mm: 250.0,
            },
            AxisConfig {
                steps_per_mm: 93.0,
                microsteps: 16,
                invert_dir: true,
                endstop: Endstop::None,
                max_feed_mm_s: 25.0,
                max_accel_mm_s2: 5000.0,
                min_mm: f32::NEG_INFINITY,
                max_mm: f32::INFINITY,
            },
        ],
        accel_print_mm_s2: 500.0,
        accel_travel_mm_s2: 500.0,
        accel_retract_mm_s2: 500.0,
        junction_deviation_mm: 0.08,
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
        driver_current_ma: [580, 580, 580, 650],
        driver_stealthchop: [true; AXES],
    };

    /// The configuration of one axis.
    pub fn axis(&self, axis: Axis) -> &AxisConfig {
        &self.axes[axis.index()]
    }

    /// Bit i set: DIR high moves axis i in the positive direction (what the step pins need).
    pub fn dir_high_positive_mask(&self) -> u8 {
        self.axes
            .iter()
            .enumerate()
            .filter(|(_, a)| !a.invert_dir)
            .fold(0, |m, (i, _)| m | 1 << i)
    }

    /// Bit i set: the endstop of axis i reads high when hit (X, Y, Z only).
    pub fn endstop_hit_high_mask(&self) -> u8 {
        self.axes
            .iter()
            .take(3)
            .enumerate()
            .filter(|(_, a)| matches!(a.endstop, Endstop::Min { hit_high: true }))
            .fold(0, |m, (i, _)| m | 1 << i)
    }

    /// Sets the microsteps of `axis` and scales its steps/mm in proportion, so a distance in
    /// mm stays the same distance (Marlin's M350 does the same). Refuses (returns false,
    /// nothing changed) a value the TMC2209 does not have: 1, 2, 4, ..., 256.
    pub fn set_microsteps(&mut self, axis: Axis, microsteps: u16) -> bool {
        if !microsteps.is_power_of_two() || microsteps > 256 {
            return false;
        }
        let a = &mut self.axes[axis.index()];
        a.steps_per_mm *= f32::from(microsteps) / f32::from(a.microsteps.max(1));
        a.microsteps = microsteps;
        true
    }
}

impl Default for MachineConfig {
    fn default() -> Self {
        Self::ENDER3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ender3_directions_and_endstops() {
        let c = MachineConfig::ENDER3;
        // Only Z has DIR high = positive (X, Y, E0 inverted as in Marlin's TMC Ender-3 configs).
        assert_eq!(c.dir_high_positive_mask(), 0b0100);
        assert_eq!(c.endstop_hit_high_mask(), 0b111);
        assert_eq!(c.axis(Axis::E).endstop, Endstop::None);
    }

    #[test]
    fn ender3_corner_speed_is_about_marlins_jerk() {
        let c = MachineConfig::ENDER3;
        let sin_half = core::f32::consts::FRAC_1_SQRT_2;
        let v = libm::sqrtf(
            c.accel_print_mm_s2 * c.junction_deviation_mm * sin_half / (1.0 - sin_half),
        );
        assert!((9.0..11.0).contains(&v), "90° corner at {v} mm/s");
    }

    #[test]
    fn microsteps_scale_steps_per_mm() {
        let mut c = MachineConfig::ENDER3;
        assert!(c.set_microsteps(Axis::X, 32));
        assert_eq!(c.axis(Axis::X).steps_per_mm, 160.0);
        assert!(c.set_microsteps(Axis::E, 8));
        assert_eq!(c.axis(Axis::E).steps_per_mm, 46.5);
        assert!(!c.set_microsteps(Axis::Y, 12));
        assert!(!c.set_microsteps(Axis::Y, 512));
        assert_eq!(c.axis(Axis::Y).steps_per_mm, 80.0);
        assert_eq!(c.axis(Axis::Y).microsteps, 16);
    }
}
