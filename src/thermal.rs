//! The thermal bias curve, per axis: `b(T) = p1 (T - t0) + p2` (paper eq. 20).
//!
//! The estimator uses it in two ways: as an absolute prior for the bias when
//! nothing has been learned yet (`bias`), and, once the EKF has held a bias,
//! as a *change* from the temperature at that moment (`delta`): the curve is
//! anchored at the last EKF bias, because the turn-on bias differs from run to
//! run while the thermal trend does not.

use crate::config::ThermalConfig;

#[derive(Clone, Debug, PartialEq)]
pub struct Thermal {
    pub t0: f64,
    pub p1: [f64; 3],
    pub p2: [f64; 3],
}

impl Thermal {
    pub fn new(c: &ThermalConfig) -> Thermal {
        Thermal { t0: c.t0, p1: c.p1, p2: c.p2 }
    }

    /// Absolute curve value at `t`, deg/s.
    pub fn bias(&self, t: f64) -> [f64; 3] {
        let d = t - self.t0;
        [self.p1[0] * d + self.p2[0], self.p1[1] * d + self.p2[1], self.p1[2] * d + self.p2[2]]
    }

    /// Change of the curve from `t_from` to `t_to`, deg/s.
    pub fn delta(&self, t_from: f64, t_to: f64) -> [f64; 3] {
        let d = t_to - t_from;
        [self.p1[0] * d, self.p1[1] * d, self.p1[2] * d]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchored_curve_telescopes() {
        let th = Thermal { t0: 25.0, p1: [0.002, 0.0044, 0.0192], p2: [0.0011, 0.0003, 0.0012] };
        assert_eq!(th.bias(25.0), [0.0011, 0.0003, 0.0012]);
        // anchor at an EKF bias of 0.3 deg/s at 30 C, then warm to 42 C in steps
        let mut b = 0.3;
        let mut t = 30.0;
        for k in 1..=120 {
            let tn = 30.0 + 0.1 * k as f64;
            b += th.delta(t, tn)[2];
            t = tn;
        }
        assert!((b - (0.3 + 0.0192 * 12.0)).abs() < 1e-12);
    }
}
