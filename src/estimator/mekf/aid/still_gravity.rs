//! Gravity at a still unit: the tick's mean specific force is gravity,
//! which tells roll and pitch.

use crate::estimator::mekf::*;

/// The tilt error seen in `u`, the measured specific force's direction in
/// the navigation frame (unit; `-e_z` when the tilt is right): the rotation
/// that takes `u` to `-e_z` is `(dθ_x, dθ_y, 0)`; returned as the
/// innovations `(dθ_y, -dθ_x)` of the rows `h[TH + 1] = 1` and
/// `h[TH] = -1`. Near level this is `(u_x, u_y)`; it stays the whole angle
/// far from it (a filter upside down sees 180 deg, not `|u_xy|` ≈ 0, which
/// would hold it there).
pub(in crate::estimator::mekf) fn tilt_innovation(u: &[f64; 3]) -> [f64; 2] {
    let s = (u[0] * u[0] + u[1] * u[1]).sqrt();
    let k = if s > 1e-12 { quat::atan2(s, -u[2]) / s } else { 1.0 };
    [k * u[0], k * u[1]]
}

impl Mekf {
    /// The tick's mean specific force as gravity, its noise the rest
    /// detector's accelerometer variance over the tick's samples (at least
    /// `tilt_floor`).
    ///
    /// In a cruise the tilt's error has run into the velocity since the
    /// tilt was last right (the velocity integrates g times it): the update
    /// corrects that velocity too, by their covariance, as every update of
    /// this filter does. It is not scored for the power-on bank: a copy
    /// fuses it as a cruise's only once a standstill has read its bias, and
    /// a copy that took the first stop for a cruise never has (scored in the
    /// published filter alone, one refused tick of a smooth pull-away put 16
    /// nats against it and published a 6 m/s copy of a car doing 2.3:
    /// `smooth` seed 8).
    pub(in crate::estimator::mekf) fn fuse_still_gravity(&mut self, a: &Accum, gate: f64) -> Rows {
        let n = a.n as f64;
        let f = [a.accel[0] / n, a.accel[1] / n, a.accel[2] / n];
        let fnm = norm(&f);
        if fnm <= 0.5 {
            let s = Rows::default();
            self.aid.set(Aid::StillGravity, s.status);
            return s;
        }
        let u = rotate(self.core.c(), &[f[0] / fnm, f[1] / fnm, f[2] / fnm]);
        let avar = self.last_rest.map_or(1e-4, |r| r.accel_var / 3.0);
        let r_tilt = (avar / n).max(self.p.tilt_floor);
        let nu = tilt_innovation(&u);
        let gain = Gain { tilt: true, heading: true, bias: true, scored: false };
        let mut h = [0.0; N];
        h[TH + 1] = 1.0;
        let mut s = Rows::default();
        s.push(self.update(&h, nu[0], r_tilt, gain, gate));
        let mut h = [0.0; N];
        h[TH] = -1.0;
        s.push(self.update(&h, nu[1], r_tilt, gain, gate));
        self.aid.set(Aid::StillGravity, s.status);
        s
    }
}
