//! The thermal bias curve, per axis, and the field learner of its slope.
//!
//! Curve (`[thermal]` of the config):
//! `b(T) = p2 + p1 (T - t0) + p3 (T - t0)^2 + p4 (T - t0)^3`, deg/s, with
//! `p3` used from `order = 2` and `p4` at `order = 3`. Order 1 is the paper's
//! eq. 20, `W = p1 (T - T0) + p2`. Outside the calibrated range
//! `[t_min, t_max]` the curve is evaluated at the nearest edge (flat
//! extrapolation: a polynomial fitted over 0..75 deg C says nothing
//! trustworthy at -20 deg C); [`Thermal::clamps`] tells the estimator to raise
//! `flags::THERMAL_CLAMP`.
//!
//! The estimator uses it in two ways: as an absolute prior for the bias when
//! nothing has been learned yet (`bias`), and, once the EKF has held a bias,
//! as a *change* from the temperature at that moment (`delta`): the curve is
//! anchored at the last EKF bias, because the turn-on bias differs from run to
//! run while the thermal trend does not.
//!
//! [`SlopeLearner`] refines the linear coefficient in the field (see there).

use crate::config::ThermalConfig;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq)]
pub struct Thermal {
    pub t0: f64,
    /// Linear coefficient, deg/s per deg C (the configured one plus any learned correction).
    pub p1: [f64; 3],
    /// Value at t0, deg/s.
    pub p2: [f64; 3],
    /// Quadratic coefficient, deg/s per (deg C)^2 (order >= 2).
    pub p3: [f64; 3],
    /// Cubic coefficient, deg/s per (deg C)^3 (order 3).
    pub p4: [f64; 3],
    /// 1, 2 or 3.
    pub order: u8,
    /// Calibrated range; -inf / +inf when not given.
    pub t_min: f64,
    pub t_max: f64,
}

impl Thermal {
    pub fn new(c: &ThermalConfig) -> Thermal {
        let o = c.order.clamp(1, 3);
        Thermal {
            t0: c.t0,
            p1: c.p1,
            p2: c.p2,
            p3: if o >= 2 { c.p3 } else { [0.0; 3] },
            p4: if o >= 3 { c.p4 } else { [0.0; 3] },
            order: o,
            t_min: c.t_min.unwrap_or(f64::NEG_INFINITY),
            t_max: c.t_max.unwrap_or(f64::INFINITY),
        }
    }

    /// The paper's linear curve, unbounded.
    pub fn linear(t0: f64, p1: [f64; 3], p2: [f64; 3]) -> Thermal {
        Thermal { t0, p1, p2, p3: [0.0; 3], p4: [0.0; 3], order: 1, t_min: f64::NEG_INFINITY, t_max: f64::INFINITY }
    }

    /// True when `t` lies outside the calibrated range (the curve is clamped there).
    #[inline]
    pub fn clamps(&self, t: f64) -> bool {
        t < self.t_min || t > self.t_max
    }

    /// `t` moved to the nearest edge of the calibrated range.
    #[inline]
    pub fn clamp(&self, t: f64) -> f64 {
        // max/min, not f64::clamp: the bounds may be infinite and t is returned unchanged then.
        t.max(self.t_min).min(self.t_max)
    }

    /// The curve without `p2`, at `d = T - t0`, axis `i`.
    #[inline]
    fn shape(&self, i: usize, d: f64) -> f64 {
        d * (self.p1[i] + d * (self.p3[i] + d * self.p4[i]))
    }

    /// Absolute curve value at `t`, deg/s.
    pub fn bias(&self, t: f64) -> [f64; 3] {
        let d = self.clamp(t) - self.t0;
        if self.order == 1 {
            [self.p1[0] * d + self.p2[0], self.p1[1] * d + self.p2[1], self.p1[2] * d + self.p2[2]]
        } else {
            [0, 1, 2].map(|i| self.p2[i] + self.shape(i, d))
        }
    }

    /// Change of the curve from `t_from` to `t_to`, deg/s.
    pub fn delta(&self, t_from: f64, t_to: f64) -> [f64; 3] {
        let (a, b) = (self.clamp(t_from), self.clamp(t_to));
        if self.order == 1 {
            let d = b - a;
            [self.p1[0] * d, self.p1[1] * d, self.p1[2] * d]
        } else {
            let (da, db) = (a - self.t0, b - self.t0);
            [0, 1, 2].map(|i| self.shape(i, db) - self.shape(i, da))
        }
    }

    /// Derivative of the curve at `t`, deg/s per deg C (0 outside the range).
    pub fn slope(&self, t: f64) -> [f64; 3] {
        if self.clamps(t) {
            return [0.0; 3];
        }
        let d = t - self.t0;
        [0, 1, 2].map(|i| self.p1[i] + d * (2.0 * self.p3[i] + 3.0 * d * self.p4[i]))
    }
}

/// Settings of the [`SlopeLearner`] (from `[thermal] learn_*`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlopeParams {
    /// Within-cycle temperature spread, deg C, needed before the slope moves.
    pub min_spread: f64,
    /// Largest |learned - configured| slope per axis, deg/s per deg C.
    pub max_dev: [f64; 3],
}

/// What the slope learner keeps across power cycles (the daemon saves it with
/// the rest of its state). Sums are over all cycles so far, each cycle's
/// points centred on that cycle's own means: a new turn-on bias every cycle
/// does not disturb the slope.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SlopeState {
    /// The configured slope the sums are relative to; a state saved under
    /// another `p1` is discarded on restore.
    pub base: [f64; 3],
    /// Sum of w (T - mean T)^2, (deg C)^2 s.
    pub stt: f64,
    /// Sum of w (T - mean T)(y - mean y) per axis, deg/s deg C s.
    pub sty: [f64; 3],
    /// Largest within-cycle temperature spread seen, deg C.
    pub spread: f64,
    /// Power cycles that contributed.
    pub cycles: u32,
}

/// Field learning of the thermal slope: a weighted least-squares line through
/// `(T, y)`, where `y = b_ekf - curve_configured(T)` is the bias the EKF holds
/// in quasi-static stretches minus what the configured curve explains. Its
/// slope is the correction to `p1`. Each power cycle has its own intercept
/// (the turn-on bias), so the sums are centred per cycle (the fixed-effects
/// estimator `sum w dT dy / sum w dT^2`), updated recursively (weighted
/// Welford), O(1) per point, no allocation.
///
/// Guards against running away:
/// - the correction stays 0 until the within-cycle temperature spread
///   (max - min of the points of one power cycle, or the largest such spread
///   of an earlier cycle) reaches `min_spread`;
/// - it is clamped to `+-max_dev` per axis;
/// - non-finite points and non-positive weights are ignored.
#[derive(Clone, Debug, PartialEq)]
pub struct SlopeLearner {
    params: SlopeParams,
    past: SlopeState,
    w: f64,
    mt: f64,
    my: [f64; 3],
    mtt: f64,
    mty: [f64; 3],
    tlo: f64,
    thi: f64,
    correction: [f64; 3],
}

impl SlopeLearner {
    /// A learner for a curve whose configured slope is `base`.
    pub fn new(params: SlopeParams, base: [f64; 3]) -> SlopeLearner {
        SlopeLearner {
            params,
            past: SlopeState { base, stt: 0.0, sty: [0.0; 3], spread: 0.0, cycles: 0 },
            w: 0.0,
            mt: 0.0,
            my: [0.0; 3],
            mtt: 0.0,
            mty: [0.0; 3],
            tlo: f64::INFINITY,
            thi: f64::NEG_INFINITY,
            correction: [0.0; 3],
        }
    }

    /// Start a new power cycle from a saved state. Returns false (and keeps
    /// nothing) when the state is for another configured slope or is not sane.
    pub fn restore(&mut self, s: &SlopeState) -> bool {
        let sane = s.stt.is_finite() && s.stt >= 0.0 && s.sty.iter().all(|v| v.is_finite()) && s.spread.is_finite() && s.spread >= 0.0;
        if !sane || s.base != self.past.base {
            return false;
        }
        self.past = *s;
        self.w = 0.0;
        self.mtt = 0.0;
        self.mty = [0.0; 3];
        self.tlo = f64::INFINITY;
        self.thi = f64::NEG_INFINITY;
        self.update();
        true
    }

    /// Add one point: temperature `t` (deg C), residual bias `y` (deg/s) per
    /// axis, weight `w` (seconds of data it stands for).
    #[inline]
    pub fn push(&mut self, t: f64, y: [f64; 3], w: f64) {
        if !(w.is_finite() && w > 0.0 && t.is_finite() && y.iter().all(|v| v.is_finite())) {
            return;
        }
        let w1 = self.w + w;
        let f = w / w1;
        let dt = t - self.mt;
        self.mt += f * dt;
        self.mtt += w * dt * (t - self.mt);
        for i in 0..3 {
            let dy = y[i] - self.my[i];
            self.my[i] += f * dy;
            self.mty[i] += w * dt * (y[i] - self.my[i]);
        }
        self.w = w1;
        self.tlo = self.tlo.min(t);
        self.thi = self.thi.max(t);
        self.update();
    }

    fn update(&mut self) {
        let stt = self.past.stt + self.mtt;
        if self.spread() < self.params.min_spread || stt.is_nan() || stt <= 0.0 {
            self.correction = [0.0; 3];
            return;
        }
        for i in 0..3 {
            let c = (self.past.sty[i] + self.mty[i]) / stt;
            let m = self.params.max_dev[i];
            self.correction[i] = if c.is_finite() { c.clamp(-m, m) } else { 0.0 };
        }
    }

    /// Within-cycle temperature spread that counts for `min_spread`, deg C.
    pub fn spread(&self) -> f64 {
        let now = if self.thi >= self.tlo { self.thi - self.tlo } else { 0.0 };
        now.max(self.past.spread)
    }

    /// True once the spread allows the slope to move.
    pub fn active(&self) -> bool {
        self.spread() >= self.params.min_spread
    }

    /// Correction to the configured slope, per axis, deg/s per deg C.
    pub fn correction(&self) -> [f64; 3] {
        self.correction
    }

    /// The learned slope: configured + correction.
    pub fn slope(&self) -> [f64; 3] {
        [0, 1, 2].map(|i| self.past.base[i] + self.correction[i])
    }

    /// Everything learned so far, this cycle included, for saving.
    pub fn state(&self) -> SlopeState {
        let p = &self.past;
        let has_now = self.w > 0.0;
        SlopeState {
            base: p.base,
            stt: p.stt + self.mtt,
            sty: [0, 1, 2].map(|i| p.sty[i] + self.mty[i]),
            spread: self.spread(),
            cycles: p.cycles + has_now as u32,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper() -> Thermal {
        Thermal::linear(25.0, [0.002, 0.0044, 0.0192], [0.0011, 0.0003, 0.0012])
    }

    #[test]
    fn anchored_curve_telescopes() {
        let th = paper();
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

    #[test]
    fn linear_form_is_bit_identical_to_the_paper_formula() {
        let th = paper();
        for k in 0..100 {
            let (a, b) = (-10.0 + 0.37 * k as f64, 3.0 + 0.91 * k as f64);
            let d = th.delta(a, b);
            let want = [0.002 * (b - a), 0.0044 * (b - a), 0.0192 * (b - a)];
            assert_eq!(d, want);
            assert_eq!(th.bias(a)[2], 0.0192 * (a - 25.0) + 0.0012);
        }
    }

    #[test]
    fn polynomial_form_and_clamp() {
        let c = ThermalConfig {
            t0: 20.0,
            order: 3,
            p1: [0.01, 0.0, 0.0],
            p2: [0.5, 0.0, 0.0],
            p3: [1e-4, 0.0, 0.0],
            p4: [-2e-6, 0.0, 1e-6],
            t_min: Some(0.0),
            t_max: Some(60.0),
            ..Default::default()
        };
        let th = Thermal::new(&c);
        let f = |t: f64| {
            let d = t - 20.0;
            0.5 + 0.01 * d + 1e-4 * d * d - 2e-6 * d * d * d
        };
        for t in [0.0, 13.0, 20.0, 47.5, 60.0] {
            assert!((th.bias(t)[0] - f(t)).abs() < 1e-12, "{t}");
            assert!(!th.clamps(t));
        }
        assert!((th.delta(10.0, 50.0)[0] - (f(50.0) - f(10.0))).abs() < 1e-12);
        // outside: the nearest edge, and flagged
        assert!(th.clamps(-5.0) && th.clamps(61.0));
        assert_eq!(th.bias(-5.0), th.bias(0.0));
        assert_eq!(th.bias(90.0), th.bias(60.0));
        assert!((th.delta(50.0, 90.0)[0] - (f(60.0) - f(50.0))).abs() < 1e-12);
        assert_eq!(th.delta(70.0, 90.0), [0.0; 3]);
        assert_eq!(th.slope(80.0), [0.0; 3]);
        let d = 30.0;
        assert!((th.slope(50.0)[0] - (0.01 + 2e-4 * d - 6e-6 * d * d)).abs() < 1e-12);
        // order 1 ignores p3/p4 even if present in the struct given
        let th1 = Thermal::new(&ThermalConfig { order: 1, ..c.clone() });
        assert_eq!(th1.p3, [0.0; 3]);
        assert_eq!(th1.p4, [0.0; 3]);
    }

    fn params() -> SlopeParams {
        SlopeParams { min_spread: 5.0, max_dev: [0.01; 3] }
    }

    #[test]
    fn learner_recovers_slope_with_per_cycle_offsets() {
        // true correction +0.006 on z, -0.001 on x; two power cycles with very
        // different turn-on biases and overlapping temperatures
        let base = [0.002, 0.0044, 0.0192];
        let mut l = SlopeLearner::new(params(), base);
        let corr = [-0.001, 0.0, 0.006];
        let mut noise = 0.0f64;
        for k in 0..2000 {
            let t = 20.0 + 10.0 * k as f64 / 2000.0;
            noise = (noise * 1.7 + 0.37).fract();
            let y = [0, 1, 2].map(|i| 0.3 + corr[i] * t + 0.002 * (noise - 0.5));
            l.push(t, y, 0.5);
        }
        let s = l.state();
        assert_eq!(s.cycles, 1);
        let mut l2 = SlopeLearner::new(params(), base);
        assert!(l2.restore(&s));
        assert!(l2.active(), "the spread of cycle 1 carries over");
        for k in 0..2000 {
            let t = 25.0 + 5.0 * k as f64 / 2000.0;
            let y = [0, 1, 2].map(|i| -0.7 + corr[i] * t);
            l2.push(t, y, 0.5);
        }
        for i in 0..3 {
            assert!((l2.correction()[i] - corr[i]).abs() < 1e-4, "{:?}", l2.correction());
            assert!((l2.slope()[i] - base[i] - corr[i]).abs() < 1e-4);
        }
        assert_eq!(l2.state().cycles, 2);
    }

    #[test]
    fn learner_waits_for_spread_and_stays_bounded() {
        let mut l = SlopeLearner::new(params(), [0.0; 3]);
        // 4.9 C of spread with a huge apparent slope: must not move
        for k in 0..1000 {
            let t = 30.0 + 4.9 * k as f64 / 999.0;
            l.push(t, [t, -t, 0.001 * t], 1.0);
        }
        assert!(!l.active());
        assert_eq!(l.correction(), [0.0; 3]);
        l.push(35.2, [35.2, -35.2, 0.0352], 1.0);
        assert!(l.active());
        let c = l.correction();
        assert_eq!(c[0], 0.01);
        assert_eq!(c[1], -0.01);
        assert!((c[2] - 0.001).abs() < 1e-9);
        // garbage is ignored
        let before = l.clone();
        l.push(f64::NAN, [0.0; 3], 1.0);
        l.push(30.0, [f64::INFINITY, 0.0, 0.0], 1.0);
        l.push(30.0, [0.0; 3], 0.0);
        assert_eq!(l, before);
    }

    #[test]
    fn learner_refuses_state_of_another_curve() {
        let l = SlopeLearner::new(params(), [0.001; 3]);
        let mut s = l.state();
        let mut other = SlopeLearner::new(params(), [0.002; 3]);
        assert!(!other.restore(&s));
        s.base = [0.002; 3];
        s.stt = f64::NAN;
        assert!(!other.restore(&s));
    }
}
