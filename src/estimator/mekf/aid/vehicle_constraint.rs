//! The ground-vehicle constraint: a car moves along its own x axis, with
//! no lateral and no vertical velocity at its rear axle (`[mounting]
//! lever_arm` from there to the sensor), along the car's axes as the
//! pull-aways have found them (`forward_axis`). The row of a body axis'
//! velocity is shared with the free unit's bound, the wheel speed and the
//! forward-speed bound.

use crate::estimator::mekf::*;

/// The constraint's own state: how long it has been refused without a
/// break, and the low-passed share of the time it is refused (what the
/// recovery rules `velocity_reacquire` and `restart_lost` read).
#[derive(Clone, Debug, Default)]
pub(in crate::estimator::mekf) struct VelocityRefusals {
    /// Seconds in motion with the velocity constraints refused, without a break.
    pub refused_s: f64,
    /// Low-passed share of the time the velocity constraints were refused.
    pub share: f64,
}

impl VelocityRefusals {
    /// One moving tick of `t` s: fused any row, refused any row.
    pub fn tick(&mut self, t: f64, fused: bool, refused: bool) {
        let k = (t / LOST_TAU_S).min(1.0);
        self.share += ((if refused && !fused { 1.0 } else { 0.0 }) - self.share) * k;
        self.refused_s = if refused { self.refused_s + t } else { 0.0 };
    }
}

impl Mekf {
    /// The car's lateral and vertical velocity at the rear axle are zero
    /// (`nhc_var`). Returns its status.
    pub(in crate::estimator::mekf) fn fuse_vehicle_constraint(&mut self, omega: &[f64; 3], gain: Gain, gate: f64) -> Rows {
        let mut s = Rows::default();
        for i in [1, 2] {
            let (nu, h) = self.body_velocity_row(i, omega);
            s.push(self.update(&h, -nu, self.p.nhc_var, Gain { scored: true, ..gain }, gate));
        }
        self.aid.set(Aid::VehicleConstraint, s.status);
        s
    }

    /// Body-axis `i` velocity at the rear axle and its row of H.
    pub(in crate::estimator::mekf) fn body_velocity_row(&self, i: usize, omega: &[f64; 3]) -> (f64, [f64; N]) {
        // a car's constraint holds along its own axes (`forward_axis`)
        let (ax, l) = if self.vehicle {
            (self.axes.rows[i], self.axes.lever)
        } else {
            let mut e = [0.0; 3];
            e[i] = 1.0;
            (e, self.p.lever)
        };
        let vb = rotate_t(self.core.c(), self.core.v());
        let wl = cross(omega, &l);
        let val = (0..3).map(|k| ax[k] * (vb[k] - wl[k])).sum::<f64>();
        // the axis in NED
        let ci = rotate(self.core.c(), &ax);
        let hth = cross(&ci, self.core.v());
        // -a^T [l×]
        let lx = [[0.0, -l[2], l[1]], [l[2], 0.0, -l[0]], [-l[1], l[0], 0.0]];
        let mut h = [0.0; N];
        for j in 0..3 {
            h[TH + j] = hth[j];
            h[VE + j] = ci[j];
            h[BI + j] = -(0..3).map(|k| ax[k] * lx[k][j]).sum::<f64>();
        }
        (val, h)
    }
}
