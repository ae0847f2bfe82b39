//! The wheel speed (`[speed]`): the vehicle's speed from its wheels, a
//! measurement of the forward velocity at the rear axle with a scale error
//! learned (`v_true = (1 + s) v_wheel`). Each frame is fused once; at a
//! standstill the zero velocity says it.

use crate::estimator::mekf::*;

/// The source's own state: the latest speed while fresh, whether a frame
/// arrived since the last tick, and how long the wheels have read standing.
#[derive(Clone, Debug, Default)]
pub(in crate::estimator::mekf) struct WheelSpeed {
    /// m/s, None when stale or absent.
    pub speed: Option<f64>,
    pub new: bool,
    /// Seconds the wheels have read standing (`WHEEL_STANDING`).
    pub standing_s: f64,
}

impl WheelSpeed {
    /// The latest speed (m/s) while fresh; `new` when it arrived since the
    /// previous sample.
    pub fn set(&mut self, v: Option<f64>, new: bool) {
        self.speed = v;
        self.new |= new && v.is_some();
    }

    /// One tick of `t` s with the wheels' speed as fused: whether they read
    /// standing.
    pub fn standing(&mut self, wheel: Option<f64>, t: f64) -> bool {
        let standing = wheel.is_some_and(|v| v.abs() < WHEEL_STANDING);
        self.standing_s = if standing { self.standing_s + t } else { 0.0 };
        standing
    }
}

impl Mekf {
    /// The wheels' speed `vw` (m/s) as the forward velocity at the rear
    /// axle, when a new frame arrived, the unit is not at rest and the tick
    /// is not suspect. Returns its status.
    pub(in crate::estimator::mekf) fn fuse_wheel_speed(
        &mut self,
        wheel: Option<f64>,
        omega: &[f64; 3],
        at_rest: bool,
        suspect: bool,
        learn: bool,
    ) -> AidStatus {
        let s = match wheel {
            None => AidStatus::NotApplicable(Why::NoSpeed),
            Some(_) if !self.wheel.new => AidStatus::NotApplicable(Why::NoNewFrame),
            Some(_) if at_rest => AidStatus::NotApplicable(Why::AtRest),
            Some(_) if suspect => AidStatus::NotApplicable(Why::Suspect),
            Some(vw) => {
                let (val, mut h) = self.body_velocity_row(0, omega);
                h[SC] = -vw;
                let nu = vw * (1.0 + self.core.scale()) - val;
                let gain = Gain { tilt: true, heading: true, bias: learn, scored: true };
                self.update(&h, nu, self.p.speed_var, gain, self.p.gate)
            }
        };
        self.wheel.new = false;
        self.aid.set(Aid::WheelSpeed, s);
        s
    }
}
