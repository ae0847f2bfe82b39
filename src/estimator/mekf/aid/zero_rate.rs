//! Zero rate: a still unit (a standstill, or a straight cruise) turns at
//! nothing the gyro can see, so the tick's mean raw rate is the bias, on
//! all three axes. The strongest bias information a vehicle gets.

use crate::estimator::mekf::*;

impl Mekf {
    /// The tick's mean raw rate as the bias, its noise the rest detector's
    /// gyro variance over the tick's samples (at least `zru_floor`).
    /// Returns the status and whether every axis was fused (the bias read).
    pub(in crate::estimator::mekf) fn fuse_zero_rate(&mut self, a: &Accum, gate: f64) -> (Rows, bool) {
        let n = a.n as f64;
        let all = Gain { tilt: true, heading: true, bias: true, scored: false };
        let gvar = self.last_rest.map_or(self.p.zru_floor, |r| r.gyro_var / 3.0);
        let r_zru = (gvar / n).max(self.p.zru_floor);
        let mut read = 0;
        let mut s = Rows::default();
        for i in 0..3 {
            let mut h = [0.0; N];
            h[BI + i] = 1.0;
            let u = self.update(&h, a.gyro[i] / n - self.core.bias()[i], r_zru, all, gate);
            read += u.is_fused() as u32;
            s.push(u);
        }
        self.aid.set(Aid::ZeroRate, s.status);
        (s, read == 3)
    }
}
