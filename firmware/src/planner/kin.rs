//! Block kinematics: length, direction, speed and acceleration limits of a straight move in
//! steps, and the junction speed between two moves (junction deviation). Pure functions, `libm`
//! for every square root so the host and the MCU compute the same bits.

use crate::config::MachineConfig;
use crate::motion::{Axis, AXES};

/// Correctly rounded single-precision square root, the same bits on every target.
///
/// On ARM with a hardware FPU (`eabihf`: the Cortex-M4F's FPv4-SP) this is one `VSQRT.F32`
/// instruction, which IEEE 754 requires to be correctly rounded, exactly like `libm::sqrtf`
/// (musl's correctly rounded software square root) that every other target uses. `libm` has no
/// hardware path on 32-bit ARM, where its bit-by-bit loop costs a few hundred instructions.
#[inline(always)]
pub fn sqrtf(x: f32) -> f32 {
    #[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
    {
        let bits: u32;
        // SAFETY: saves S0, takes the square root in it and restores it; touches nothing else
        // (registers named in the template, so no `sreg` operand: stable Rust does not expose
        // the `vfp2` target feature that operand class needs, the assembler knows the FPU).
        unsafe {
            core::arch::asm!(
                "vpush {{s0}}",
                "vmov s0, {x}",
                "vsqrt.f32 s0, s0",
                "vmov {r}, s0",
                "vpop {{s0}}",
                x = in(reg) x.to_bits(),
                r = lateout(reg) bits,
                options(pure, nomem),
            );
        }
        f32::from_bits(bits)
    }
    #[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
    {
        libm::sqrtf(x)
    }
}

/// `a.min(b)` (the other value when one is NaN) as two compares: `f32::min` is a library call
/// (`fminf`) on cores without VMINNM such as the Cortex-M4.
#[inline(always)]
pub fn fmin(a: f32, b: f32) -> f32 {
    if a.is_nan() || b < a {
        b
    } else {
        a
    }
}

/// `a.max(b)` (the other value when one is NaN) as two compares; see [`fmin`].
#[inline(always)]
pub fn fmax(a: f32, b: f32) -> f32 {
    if a.is_nan() || b > a {
        b
    } else {
        a
    }
}

/// Kinematic summary of one straight move (or of every segment of it: the segments of one move
/// share direction, nominal speed and acceleration).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Kin {
    /// Path length in mm: XYZ length, or |E| for an extruder-only move.
    pub len_mm: f32,
    /// Unit direction over X, Y, Z, E (each component in mm per mm of path).
    pub unit: [f32; AXES],
    /// Requested speed after per-axis feed limits, mm/s (before any pause speed-up).
    pub nominal_mm_s: f32,
    /// Highest speed this move may ever run at (per-axis feed limits), mm/s.
    pub cap_mm_s: f32,
    /// Acceleration along the path, mm/s² (M204 P/T/R, then per-axis limits).
    pub accel_mm_s2: f32,
    /// Filament length per mm of path (|E mm| / path mm); 0 for travel.
    pub e_per_mm: f32,
}

/// Kinematics of the straight move `delta` (steps) at `feed_mm_s`. `None` when the move has no
/// step on any axis, or when the feed is not a positive finite number.
pub fn kinematics(cfg: &MachineConfig, delta: &[i32; AXES], feed_mm_s: f32) -> Option<Kin> {
    let mut mm = [0.0f32; AXES];
    for (i, m) in mm.iter_mut().enumerate() {
        *m = delta[i] as f32 / cfg.axes[i].steps_per_mm;
    }
    let xyz2 = mm[0] * mm[0] + mm[1] * mm[1] + mm[2] * mm[2];
    let e = Axis::E.index();
    let (len, base_accel) = if xyz2 > 0.0 {
        let a = if delta[e] != 0 {
            cfg.accel_print_mm_s2
        } else {
            cfg.accel_travel_mm_s2
        };
        (sqrtf(xyz2), a)
    } else if delta[e] != 0 {
        (libm::fabsf(mm[e]), cfg.accel_retract_mm_s2)
    } else {
        return None;
    };
    if len.partial_cmp(&0.0) != Some(core::cmp::Ordering::Greater) {
        return None;
    }
    let feed = if feed_mm_s.is_finite() && feed_mm_s > 0.0 {
        feed_mm_s
    } else {
        cfg.default_feed_mm_s
    };
    let inv = 1.0 / len;
    let mut unit = [0.0f32; AXES];
    let mut cap = f32::INFINITY;
    let mut accel = base_accel;
    for i in 0..AXES {
        unit[i] = mm[i] * inv;
        let r = libm::fabsf(unit[i]);
        if r > 0.0 {
            cap = fmin(cap, cfg.axes[i].max_feed_mm_s / r);
            accel = fmin(accel, cfg.axes[i].max_accel_mm_s2 / r);
        }
    }
    Some(Kin {
        len_mm: len,
        unit,
        nominal_mm_s: fmin(feed, cap),
        cap_mm_s: cap,
        accel_mm_s2: accel,
        e_per_mm: libm::fabsf(unit[e]),
    })
}

/// Square of the highest speed at the corner between a move along `prev` and one along `next`
/// (unit vectors), by junction deviation `dev_mm` at acceleration `accel_mm_s2`: the speed at
/// which a circular arc that deviates `dev_mm` from the corner is taken at `accel_mm_s2`
/// centripetal acceleration. Collinear: unlimited (`f32::INFINITY`); reversal: 0.
pub fn junction_v2(prev: &[f32; AXES], next: &[f32; AXES], dev_mm: f32, accel_mm_s2: f32) -> f32 {
    let mut dot = 0.0f32;
    for i in 0..AXES {
        dot += prev[i] * next[i];
    }
    // cos of the angle between the incoming and the reversed outgoing direction.
    let cos_theta = -dot;
    if cos_theta > 0.999_999 {
        return 0.0;
    }
    if cos_theta < -0.999_999 {
        return f32::INFINITY;
    }
    let sin_half = sqrtf(0.5 * (1.0 - cos_theta));
    accel_mm_s2 * dev_mm * sin_half / (1.0 - sin_half)
}

/// Distance a feed hold may run beyond `v²/2a` (`a`: the acceleration of the block executing at
/// the request), mm: less than one step of an Ender-3 X/Y axis (1/80 mm).
pub const HOLD_SLACK_MM: f32 = 0.01;

/// Square of the highest speed at which a block of acceleration `accel_mm_s2` may be entered
/// from one of acceleration `prev_accel_mm_s2`, so that a feed hold still stops within the
/// braking distance of the block it starts in.
///
/// A hold brakes each block at that block's own acceleration. Entering a block of *lower*
/// acceleration (a Z move after an X/Y move: 100 vs 500 mm/s² on an Ender-3) at `v` makes a
/// hold requested at the junction run `v²/2a_new` instead of `v²/2a_prev`; the difference is
/// kept within [`HOLD_SLACK_MM`]: `v² ≤ 2·slack / (1/a_new − 1/a_prev)` (1.58 mm/s for 500 → 100,
/// where the junction deviation would allow 4.4). No limit when the acceleration does not drop.
pub fn hold_entry_v2(prev_accel_mm_s2: f32, accel_mm_s2: f32) -> f32 {
    // Both accelerations positive (NaN fails every comparison) and dropping.
    let dropping = accel_mm_s2 > 0.0 && prev_accel_mm_s2 > accel_mm_s2;
    let d = 1.0 / accel_mm_s2 - 1.0 / prev_accel_mm_s2;
    if dropping && d > 0.0 {
        2.0 * HOLD_SLACK_MM / d
    } else {
        f32::INFINITY
    }
}

/// The kinematics of a move cut into `n` segments of `seg_len_mm`, with its speeds capped so
/// that no *segment* runs an axis faster than its `max_feed_mm_s`.
///
/// Every segment is timed as `seg_len_mm` of path, but carries ⌊d/n⌋ or ⌈d/n⌉ of an axis' `d`
/// steps: a segment with the extra step runs that axis `1/(d/n)` faster than the move's
/// average (+5 % for Z in a 0.2 mm segment of a Z-hop diagonal, +9 % for X at 11.2 steps). A move
/// at an axis' limit (the feed above it, or the pause speed-up capped by it) therefore stepped
/// the axis over its limit in every other segment (found by the `executive` fuzz target). The
/// cap is the slowest segment's: `v ≤ max_feed × steps_per_mm × seg_len / ⌈|d|/n⌉` for every
/// axis, one speed for the whole move (no 5 % speed ripple from segment to segment).
/// `max_seg_steps[i]` is `⌈|d_i|/n⌉`. Unchanged for a move that is not cut (`n == 1`).
pub fn cap_for_segments(cfg: &MachineConfig, kin: Kin, max_seg_steps: &[u32; AXES], n: u32) -> Kin {
    if n <= 1 {
        return kin;
    }
    let seg_len_mm = kin.len_mm / n as f32;
    let mut cap = kin.cap_mm_s;
    for (a, &steps) in cfg.axes.iter().zip(max_seg_steps.iter()) {
        if steps > 0 {
            cap = fmin(
                cap,
                a.max_feed_mm_s * a.steps_per_mm * seg_len_mm / steps as f32,
            );
        }
    }
    Kin {
        nominal_mm_s: fmin(kin.nominal_mm_s, cap),
        cap_mm_s: cap,
        ..kin
    }
}

/// Highest speed of the pause speed-up for a move: `factor` × the nominal speed, bounded by the
/// per-axis feed limits and by the extruder's volumetric flow, never below the nominal speed.
pub fn sped_up_mm_s(kin: &Kin, factor: f32, max_vol_mm3_s: f32, filament_diameter_mm: f32) -> f32 {
    if factor.partial_cmp(&1.0) != Some(core::cmp::Ordering::Greater) {
        return kin.nominal_mm_s;
    }
    let mut v = (kin.nominal_mm_s * factor).min(kin.cap_mm_s);
    if kin.e_per_mm > 0.0 && max_vol_mm3_s > 0.0 && filament_diameter_mm > 0.0 {
        let r = 0.5 * filament_diameter_mm;
        let area = core::f32::consts::PI * r * r;
        v = v.min(max_vol_mm3_s / (area * kin.e_per_mm));
    }
    v.max(kin.nominal_mm_s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::{BlockKind, Planner};

    #[test]
    fn hold_entry_limits_only_a_drop_in_acceleration() {
        assert_eq!(hold_entry_v2(500.0, 500.0), f32::INFINITY);
        assert_eq!(hold_entry_v2(100.0, 500.0), f32::INFINITY);
        let v2 = hold_entry_v2(500.0, 100.0);
        assert!((v2 - 2.5).abs() < 1.0e-4, "{v2}");
        // A hold right at the junction runs exactly the slack beyond v²/2a_prev.
        let extra = v2 / (2.0 * 100.0) - v2 / (2.0 * 500.0);
        assert!((extra - HOLD_SLACK_MM).abs() < 1.0e-6, "{extra}");
    }

    #[test]
    fn z_move_after_xy_move_is_entered_slowly() {
        let cfg = MachineConfig::ENDER3;
        let mut p = Planner::new();
        let xy = crate::motion::MoveRequest {
            target: [80, 0, 0, 0],
            feed_mm_s: 100.0,
            seq: 1,
        };
        let z = crate::motion::MoveRequest {
            target: [80, 0, 80, 0],
            feed_mm_s: 10.0,
            seq: 2,
        };
        assert_eq!(p.push_move(&cfg, &xy, BlockKind::Job), Ok(true));
        assert_eq!(p.push_move(&cfg, &z, BlockKind::Job), Ok(true));
        let zb = (0..p.len())
            .filter_map(|k| p.get(k))
            .find(|b| b.seq == 2)
            .copied()
            .expect("z block queued");
        // Junction deviation alone: 100 · 0.08 · (√½ / (1 − √½)) = 19.3 mm²/s².
        let jd = junction_v2(
            &[1.0, 0.0, 0.0, 0.0],
            &[0.0, 0.0, 1.0, 0.0],
            cfg.junction_deviation_mm,
            zb.accel_mm_s2,
        );
        assert!(jd > 19.0, "{jd}");
        assert_eq!(zb.accel_mm_s2, 100.0);
        assert!(zb.junction_v2 <= 2.5 + 1.0e-4, "{}", zb.junction_v2);
    }

    /// The fuzz find's move: X and Y +2366 steps, Z −2000 (a Z-hop diagonal at F6000, which Z's
    /// 5 mm/s limits). Every segment the planner cuts, timed at the fast (speed-up) speed, keeps
    /// every axis within its limit, and the cap costs no more than one step's share.
    #[test]
    fn no_segment_runs_an_axis_over_its_limit() {
        let cfg = MachineConfig::ENDER3;
        let mut p = Planner::new();
        let req = crate::motion::MoveRequest {
            target: [2366, 2366, -2000, 0],
            feed_mm_s: 100.0,
            seq: 1,
        };
        assert_eq!(p.push_move(&cfg, &req, BlockKind::Job), Ok(true));
        let kin = kinematics(&cfg, &[2366, 2366, -2000, 0], 100.0).expect("a move");
        let mut seen = 0;
        while let Some(b) = p.get(0).copied() {
            for (i, a) in cfg.axes.iter().enumerate() {
                let mm = b.delta[i].unsigned_abs() as f32 / a.steps_per_mm;
                let v_axis = mm / b.len_mm * sqrtf(b.fast_v2.max(b.nominal_v2));
                assert!(
                    v_axis <= a.max_feed_mm_s * 1.0001,
                    "axis {i}: {v_axis} mm/s"
                );
            }
            assert!(sqrtf(b.fast_v2) >= kin.cap_mm_s * (1.0 - 1.0 / 9.0));
            seen += 1;
            let _ = p.pop();
            p.refill();
        }
        assert!(seen > 200, "{seen} segments");
    }
}
