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

fn line(m: &mut Model, a: [f64; 3], b: [f64; 3]) {
    m.push(Step::String(crate::design::model::Str::line(
        a.into(),
        b.into(),
        0.2,
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

/// The message names the limit the check applies: half the width plus the allowance.
#[test]
fn widening_message_states_the_limit_used() {
    let r = check(&helix(2.0), &Profile::ender3(), &CheckOptions::default());
    let i = r
        .issues
        .iter()
        .find(|i| i.kind == IssueKind::WideningTooFast);
    assert!(
        i.is_some_and(|i| i.msg.contains("plus the 0.25 mm sampling allowance")),
        "{:?}",
        r.issues
    );
}
