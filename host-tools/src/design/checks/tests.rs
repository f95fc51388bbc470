//! Tests of the checks on small designs, the parts library's helix and example-like cases.

use super::*;
use crate::design::deform;
use crate::design::parts::Helix;

fn helix(radius_growth: f64) -> Model {
    let h = Helix {
        turns: 10.0,
        ..Helix::default()
    }
    .build()
    .expect("helix");
    deform::deform_cylinder(
        h,
        |c| DVec3::new(c.x + radius_growth * c.z, c.y, c.z),
        |c, _| c,
        |v, _| v,
        None,
    )
    .expect("deform")
}

#[test]
fn plain_helix_is_clean() {
    let r = check(&helix(0.0), &Profile::ender3(), &CheckOptions::default());
    assert!(r.is_clean(), "{:?}", r.issues);
}

#[test]
fn fast_widening_is_flagged() {
    // 0.4 mm pitch, 0.2 mm² ⇒ width 0.5: offsets > 0.25 mm/turn cannot stack.
    let r = check(&helix(2.0), &Profile::ender3(), &CheckOptions::default());
    assert!(r.count(IssueKind::WideningTooFast) > 0, "{:?}", r.counts);
    let slow = check(&helix(0.2), &Profile::ender3(), &CheckOptions::default());
    assert_eq!(slow.count(IssueKind::WideningTooFast), 0);
}

#[test]
fn air_outside_and_flow() {
    let mut m = Model::new([0.0, 0.0]);
    use crate::design::model::Str;
    m.push(Step::String(Str::line(
        DVec3::new(10.0, 10.0, 0.2),
        DVec3::new(20.0, 10.0, 0.2),
        0.2,
        20.0,
    )));
    // in the air, 5 mm up
    m.push(Step::String(Str::line(
        DVec3::new(50.0, 50.0, 5.0),
        DVec3::new(60.0, 50.0, 5.0),
        0.2,
        20.0,
    )));
    m.push(Step::String(Str::line(
        DVec3::new(60.0, 50.0, 5.0),
        DVec3::new(260.0, 50.0, 5.0),
        0.2,
        200.0,
    )));
    let r = check(&m, &Profile::ender3(), &CheckOptions::default());
    assert!(r.count(IssueKind::Unsupported) >= 1);
    assert_eq!(r.count(IssueKind::OutsideBed), 1);
    assert_eq!(r.count(IssueKind::FlowTooHigh), 1);
    let first = r.issues.iter().find(|i| i.kind == IssueKind::OutsideBed);
    assert_eq!(first.map(|i| i.step), Some(2));
}

#[test]
fn travel_over_print_is_flagged() {
    use crate::design::model::Str;
    let mut m = Model::new([0.0, 0.0]);
    m.push(Step::String(Str::line(
        DVec3::new(10.0, 10.0, 0.2),
        DVec3::new(10.0, 30.0, 0.2),
        0.2,
        20.0,
    )));
    m.push(Step::Travel {
        to: DVec3::new(0.0, 20.0, 0.2),
        speed_mm_s: None,
    });
    m.push(Step::Travel {
        to: DVec3::new(20.0, 20.0, 0.2),
        speed_mm_s: None,
    });
    let r = check(&m, &Profile::ender3(), &CheckOptions::default());
    assert_eq!(r.count(IssueKind::TravelCrossesPrint), 1, "{:?}", r.issues);
}

/// A 0.4 mm × 0.2 mm line (0.08 mm²).
fn line(m: &mut Model, a: [f64; 3], b: [f64; 3]) {
    m.push(Step::String(crate::design::model::Str::line(
        a.into(),
        b.into(),
        0.08,
        20.0,
    )));
}

/// A 40 mm bridge from one pillar onto another: both ends rest on the pillars, the middle
/// is in the air.
#[test]
fn bridge_is_unsupported_in_the_middle() {
    let mut m = Model::new([0.0, 0.0]);
    for k in 0..10 {
        let z = 0.2 * (k + 1) as f64;
        line(&mut m, [100.0, 100.0, z], [101.0, 100.0, z]);
        line(&mut m, [140.0, 100.0, z], [141.0, 100.0, z]);
    }
    line(&mut m, [101.0, 100.0, 2.2], [140.0, 100.0, 2.2]);
    let r = check(&m, &Profile::ender3(), &CheckOptions::default());
    assert_eq!(r.count(IssueKind::Unsupported), 1, "{:?}", r.issues);
    let at = r.issues.iter().find(|i| i.kind == IssueKind::Unsupported);
    assert!(at.is_some_and(|i| i.at.x > 102.0 && i.at.x < 139.0));
}

#[test]
fn first_layer_at_z0_is_flagged() {
    let mut m = Model::new([0.0, 0.0]);
    line(&mut m, [100.0, 100.0, 0.0], [120.0, 100.0, 0.0]);
    let r = check(&m, &Profile::ender3(), &CheckOptions::default());
    assert_eq!(r.count(IssueKind::OutsideBed), 1, "{:?}", r.issues);
    let mut ok = Model::new([0.0, 0.0]);
    line(&mut ok, [100.0, 100.0, 0.2], [120.0, 100.0, 0.2]);
    assert!(check(&ok, &Profile::ender3(), &CheckOptions::default()).is_clean());
}

/// The message names the limit the check applies: half the width, as an angle.
#[test]
fn widening_message_states_the_limit_used() {
    let r = check(&helix(2.0), &Profile::ender3(), &CheckOptions::default());
    let i = r
        .issues
        .iter()
        .find(|i| i.kind == IssueKind::WideningTooFast);
    assert!(
        i.is_some_and(|i| i.msg.contains("half the string width") && i.msg.contains("atan(w / 2h)")),
        "{:?}",
        r.issues
    );
}

/// A wall leaning `deg` from the vertical: 10 mm lines of 0.4 × 0.2 mm, each layer shifted
/// sideways by 0.2 mm · tan(deg), printed back and forth.
fn leaning_wall(deg: f64) -> Model {
    let mut m = Model::new([0.0, 0.0]);
    let d = 0.2 * deg.to_radians().tan();
    for k in 0..20 {
        let (y, z) = (100.0 + d * k as f64, 0.2 * (k + 1) as f64);
        let (a, b) = if k % 2 == 0 {
            (100.0, 110.0)
        } else {
            (110.0, 100.0)
        };
        line(&mut m, [a, y, z], [b, y, z]);
        if k + 1 < 20 {
            let y1 = 100.0 + d * (k + 1) as f64;
            m.push(Step::Travel {
                to: DVec3::new(b, y1, z + 0.2),
                speed_mm_s: None,
            });
        }
    }
    m
}

/// The overhang check flags at the angle it documents: beyond atan(w / 2h) from the
/// vertical, 45° for lines twice as wide as high (0.4 × 0.2 mm). It used to start near
/// 50–66°: it measured the offset to the nearest *sample* of the string below (up to a
/// quarter millimetre off the string) and added that much allowance.
#[test]
fn overhang_flags_at_the_documented_angle() {
    let p = Profile::ender3();
    let o = CheckOptions::default();
    for (deg, flagged) in [
        (30.0, false),
        (44.0, false),
        (46.0, true),
        (50.0, true),
        (60.0, true),
    ] {
        let r = check(&leaning_wall(deg), &p, &o);
        assert_eq!(
            r.count(IssueKind::WideningTooFast) > 0,
            flagged,
            "{deg}°: {:?}",
            r.issues
        );
        assert_eq!(r.count(IssueKind::Unsupported), 0, "{deg}°");
    }
}

/// Widths outside 0.5–2× the nozzle are flagged (on the bed up to 2.5×: first layers are
/// squashed): 1 mm lines at 0.2 mm layers (`turtle()`'s default 0.2 mm² at 0.2 mm layers)
/// are flagged from the second layer, 0.4 mm lines are not, 0.1 mm lines everywhere.
#[test]
fn line_width_outside_the_nozzles_range_is_flagged() {
    let p = Profile::ender3();
    let o = CheckOptions::default();
    let layer = |cross: f64| {
        let mut m = Model::new([0.0, 0.0]);
        for k in 0..3 {
            let z = 0.2 * (k + 1) as f64;
            m.push(Step::String(crate::design::model::Str::line(
                DVec3::new(100.0, 100.0, z),
                DVec3::new(120.0, 100.0, z),
                cross,
                20.0,
            )));
        }
        check(&m, &p, &o)
    };
    let wide = layer(0.2);
    assert_eq!(wide.count(IssueKind::LineWidth), 2, "{:?}", wide.issues);
    assert!(
        layer(0.21).count(IssueKind::LineWidth) == 3,
        "wider than 2.5× on the bed too"
    );
    assert!(wide.issues.iter().any(|i| i.msg.contains("1.00 mm wide")));
    assert_eq!(layer(0.08).count(IssueKind::LineWidth), 0);
    assert_eq!(layer(0.02).count(IssueKind::LineWidth), 3, "0.1 mm wide");
}

/// Raw G-code is part of the design the checks see: a heater switched off before an
/// extrusion and a mid-print `G28` are flagged; `M302 P1` allows cold extrusion; homing
/// before anything is printed is fine.
#[test]
fn raw_gcode_heater_off_and_homing_are_flagged() {
    use crate::design::model::StateChange;
    let p = Profile::ender3();
    let o = CheckOptions::default();
    let with = |raw: &str| {
        let mut m = Model::new([0.0, 0.0]);
        m.push(Step::State(StateChange::Gcode("G28".into())));
        line(&mut m, [100.0, 100.0, 0.2], [120.0, 100.0, 0.2]);
        m.push(Step::State(StateChange::Gcode(raw.into())));
        line(&mut m, [120.0, 100.0, 0.2], [120.0, 120.0, 0.2]);
        line(&mut m, [120.0, 120.0, 0.2], [100.0, 120.0, 0.2]);
        check(&m, &p, &o)
    };
    let r = with("M104 S0\nG28");
    assert_eq!(r.count(IssueKind::ColdExtrusion), 1, "{:?}", r.issues);
    assert_eq!(r.count(IssueKind::HomesMidPrint), 1, "{:?}", r.issues);
    let cold = r.issues.iter().find(|i| i.kind == IssueKind::ColdExtrusion);
    assert!(cold.is_some_and(|i| i.step == 3 && i.msg.contains("0 °C") && i.msg.contains("step 2")));
    assert!(
        with("M106 S100").is_clean(),
        "{:?}",
        with("M106 S100").issues
    );
    assert_eq!(with("M302 P1\nM104 S0").count(IssueKind::ColdExtrusion), 0);
    assert_eq!(with("M104 S150").count(IssueKind::ColdExtrusion), 1);
    // The design's own temperature change counts the same.
    let mut m = Model::new([0.0, 0.0]);
    line(&mut m, [100.0, 100.0, 0.2], [120.0, 100.0, 0.2]);
    m.push(Step::State(StateChange::HotendTemp {
        celsius: 0.0,
        wait: false,
    }));
    line(&mut m, [120.0, 100.0, 0.2], [120.0, 120.0, 0.2]);
    assert_eq!(check(&m, &p, &o).count(IssueKind::ColdExtrusion), 1);
}

/// A line that climbs in short strings (FullControl's nonplanar spacer: 0.26 mm strings of
/// 0.32 mm² rising up to 0.03 mm each) has its own trail as the nearest material more than
/// `min_drop_mm` below: that trail says nothing of the bead's thickness, and the bead is
/// not flagged as too wide (it was, 3.1× the nozzle: 0.26 mm to the trail taken for its
/// thickness). A second pass laid 0.1 mm over the first is still flagged (8×).
#[test]
fn a_climbing_line_is_not_measured_against_its_own_trail() {
    let p = Profile::ender3();
    let o = CheckOptions::default();
    let ramp = |m: &mut Model, y: f64, z0: f64| {
        let mut at = [100.0, y, z0];
        for _ in 0..60 {
            let next = [at[0] + 0.25, y, at[2] + 0.03];
            m.push(Step::String(crate::design::model::Str::line(
                DVec3::from_array(at),
                DVec3::from_array(next),
                0.32,
                20.0,
            )));
            at = next;
        }
    };
    let mut m = Model::new([0.0, 0.0]);
    ramp(&mut m, 100.0, 0.4); // 0.32 mm² at 0.43 mm over the bed: 1.9×
    let r = check(&m, &p, &o);
    assert_eq!(r.count(IssueKind::LineWidth), 0, "{:?}", r.issues);
    assert_eq!(r.count(IssueKind::Unsupported), 0, "{:?}", r.issues);
    m.push(Step::Travel {
        to: DVec3::new(100.0, 100.0, 0.5),
        speed_mm_s: Some(100.0),
    });
    ramp(&mut m, 100.0, 0.5);
    let r = check(&m, &p, &o);
    assert!(r.count(IssueKind::LineWidth) > 30, "{:?}", r.counts);
}
