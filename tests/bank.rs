//! The power-on speed hypotheses (`src/estimator/hypotheses.rs`) compare
//! their copies by the likelihood of what every copy measures alike: the
//! velocity constraints and the wheel speed, never an update only some
//! copies make.

use gyrocomp::adis::RawFrame;
use gyrocomp::config::Config;
use gyrocomp::estimator::Estimate;
use gyrocomp::output::Frames;
use gyrocomp::pipeline::{Pipeline, Sink};
use gyrocomp::sim::{self, SimOptions};

struct Keep(Option<Estimate>);

impl Sink for Keep {
    fn output(&mut self, e: &Estimate, _: &Frames) {
        self.0 = Some(*e);
    }
}

/// `smooth` seed 8: parked at power-on (a standstill at 2-7 s), then a
/// pull-away from 0 to 12 m/s over 24 s at 0.05 g, inside the rest band:
/// many of its ticks are still, and with the velocity refusing a stop, a
/// cruise. The published filter read its bias at the standstill and fuses
/// a cruise's gravity; a copy that took the standstill for a cruise never
/// read its bias and does not. Scored in the published filter alone, its
/// first refused tick put 16 nats against it and published the 6 m/s copy
/// at 12 s: 8.4 m/s believed at a true 2.3. With `accelerating` switched
/// off the cruise's gravity is refused as it was before that rule.
#[test]
fn a_gravity_only_some_copies_fuse_does_not_publish_a_faster_copy() {
    let o = SimOptions::new("smooth", 8);
    let run = sim::prepare(&o).unwrap();
    let cfg = Config::parse(&(run.config_toml.clone() + "\n[mekf]\nablate = [\"accelerating\"]\n"), "smooth 8").unwrap();
    let mut pipe = Pipeline::with_speed(&cfg, None);
    let mut worst: f64 = 0.0;
    let mut refused = 0;
    'run: for b in sim::bus(&run, 8) {
        let speed = b.truth.speed;
        for f in b.frames() {
            let mut k = Keep(None);
            pipe.push(f.t_us, RawFrame::classic(f.id, &f.data), &mut k);
            let Some(e) = k.0 else { continue };
            if e.t > 25.0 {
                break 'run;
            }
            let m = pipe.estimator().mekf().unwrap();
            refused += (e.aid.code(gyrocomp::estimator::mekf::Aid::StillGravity) == 2) as u32;
            if e.t > 8.0 {
                worst = worst.max((m.forward_speed() - speed).abs());
            }
        }
    }
    let p = pipe.estimator().power_on_speed().unwrap();
    assert!(refused > 0, "the case is gone: no cruise's gravity was refused");
    assert!(p.speed_ms == 0.0, "a copy of another power-on speed was published: {p:?}");
    assert!(worst < 1.5, "the published speed was {worst:.2} m/s off the truth");
}
