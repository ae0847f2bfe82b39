//! The default filter's aid sources say what they did (`mekf::aid`): per
//! tick in the estimate (`Estimate::aid`, the `EST_AID` frame) and the
//! filter's report, and over the run in its counters.

use super::*;
use crate::estimator::mekf::{Aid, AidStatus, Why};

/// A level unit standing still, heading 30 deg, with a constant bias.
fn still(e: &mut Estimator, from: u16, n: u16, bias: [f64; 3]) -> Estimate {
    let mut est = Estimate::default();
    for k in from..from + n {
        est = e.step(&rest(k, bias, 30.0, 25.0));
    }
    est
}

fn mekf(extra: &str) -> Estimator {
    Estimator::new(&Config::parse(&format!("[estimator]\nmode = \"mekf\"\n{extra}"), "test").unwrap())
}

fn status(e: &Estimator, a: Aid) -> AidStatus {
    e.mekf().unwrap().aid_report().get(a)
}

#[test]
fn a_parked_car_fuses_its_standstill_and_not_its_motion_constraints() {
    let mut e = mekf("");
    let est = still(&mut e, 0, 2048, [0.4, -0.3, 0.2]);
    for a in [Aid::ZeroVelocity, Aid::ZeroRate, Aid::StillGravity, Aid::Heading] {
        assert!(status(&e, a).is_fused(), "{}: {}", a.name(), status(&e, a));
        assert_eq!(est.aid.code(a), 1, "{}", a.name());
    }
    for a in [Aid::VehicleConstraint, Aid::LevelRate, Aid::ForwardSpeed] {
        assert_eq!(status(&e, a), AidStatus::NotApplicable(Why::Still), "{}", a.name());
        assert_eq!(est.aid.code(a), 0, "{}", a.name());
    }
    assert_eq!(status(&e, Aid::WheelSpeed), AidStatus::NotApplicable(Why::NoSpeed));
    let c = e.mekf_counters().unwrap().aid;
    let (fused, refused, _) = c.get(Aid::ZeroVelocity);
    assert!(fused > 100 && refused == 0, "{c}");
    assert!(c.to_string().contains("zero_velocity"), "{c}");
}

#[test]
fn a_standstill_whose_gravity_contradicts_a_settled_tilt_is_refused_with_its_ratio() {
    // 10 s level at rest settle the tilt to a few hundredths of a degree;
    // then the specific force leans 5 deg with no rotation the gyro saw (a
    // unit knocked in its mount): gravity at the standstill is refused, its
    // test ratio above 1 (the gate), and the estimate carries the refusal.
    let mut e = mekf("");
    still(&mut e, 0, 2048, [0.2, 0.0, 0.0]);
    assert!(status(&e, Aid::StillGravity).is_fused());
    let (sn, cs) = (5.0 * D2R).sin_cos();
    let mut worst: f64 = 0.0;
    let mut coded = false;
    for k in 2048..2148u16 {
        let mut s = rest(k, [0.2, 0.0, 0.0], 30.0, 25.0);
        s.accel = [sn, 0.0, -cs];
        let est = e.step(&s);
        if let AidStatus::Refused(r) = status(&e, Aid::StillGravity) {
            worst = worst.max(r);
            coded |= est.aid.code(Aid::StillGravity) == 2 && est.aid.worst_ratio >= r;
        }
    }
    assert!(worst > 1.0, "gravity was never refused: worst ratio {worst}");
    assert!(coded, "the estimate did not carry the refusal");
    let (_, refused, ratio) = e.mekf_counters().unwrap().aid.get(Aid::StillGravity);
    assert!(refused > 0 && ratio == worst, "{refused} {ratio} {worst}");
}

#[test]
fn a_moving_car_fuses_its_constraint_and_says_why_the_standstill_does_not_run() {
    let mut e = mekf("");
    still(&mut e, 0, 2048, [0.0; 3]);
    // pulling away at 0.15 g along x for 3 s
    let mut s = rest(2048, [0.0; 3], 30.0, 25.0);
    for k in 2048..2048 + 614u16 {
        s.cnt = k;
        s.accel = [0.15, 0.0, -1.0];
        e.step(&s);
    }
    assert!(status(&e, Aid::VehicleConstraint).is_fused(), "{}", status(&e, Aid::VehicleConstraint));
    for a in [Aid::ZeroVelocity, Aid::ZeroRate, Aid::StillGravity] {
        assert_eq!(status(&e, a), AidStatus::NotApplicable(Why::Moving), "{}", a.name());
    }
    assert_eq!(status(&e, Aid::FreeGravity), AidStatus::NotApplicable(Why::Vehicle));
    assert_eq!(status(&e, Aid::LevelRate), AidStatus::NotApplicable(Why::BiasKnown));
}

#[test]
fn without_a_magnetometer_the_heading_is_not_applicable_and_a_disturbed_field_says_so() {
    let mut e = mekf("use_magnetometer = false");
    still(&mut e, 0, 1024, [0.0; 3]);
    assert_eq!(status(&e, Aid::Heading), AidStatus::NotApplicable(Why::NoMagnetometer));
    let mut e = mekf("");
    still(&mut e, 0, 1024, [0.0; 3]);
    assert!(status(&e, Aid::Heading).is_fused());
    // a magnet near the unit: twice the field
    let mut est = Estimate::default();
    for k in 1024..1124u16 {
        let mut s = rest(k, [0.0; 3], 30.0, 25.0);
        s.magn = s.magn.map(|m| 2.0 * m);
        est = e.step(&s);
    }
    assert_eq!(status(&e, Aid::Heading), AidStatus::NotApplicable(Why::FieldDisturbed));
    assert_ne!(est.flags & flags::MAG_DISTURBED, 0);
}

#[test]
fn the_paper_filter_carries_no_aid_sources() {
    let mut e = Estimator::new(&cfg("[estimator]\nmode = \"paper\"\n"));
    let mut est = Estimate::default();
    for k in 0..1024u16 {
        est = e.step(&rest(k, [0.1; 3], 0.0, 25.0));
    }
    assert_eq!(est.aid, crate::estimator::mekf::AidWord::default());
    assert!(e.mekf().is_none());
}
