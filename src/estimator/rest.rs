//! Standstill (rest) detection from the gyro and the accelerometer alone.
//!
//! A unit at rest measures its gyro bias on all three axes and gravity alone
//! on the accelerometer: the strongest bias information a vehicle gets. The
//! detector looks at how much the signals *move*, not at their level, so a
//! gyro bias of several deg/s does not hide a standstill:
//!
//! - the gyro and the specific force are low-passed (first order, time
//!   constant `tau_s`), and the mean square deviation of each sample from its
//!   low-passed value is low-passed alike: its square root is the signal's
//!   RMS deviation, which engine idle vibration raises a little and driving
//!   (road input, steering, speed changes) raises a lot;
//! - rest needs the gyro deviation under `gyro_dev_dps`, the accelerometer
//!   deviation under `accel_dev_g`, the low-passed |f| within `band` of
//!   gravity as this unit measures it (a steady 0.2 g acceleration is 2 %
//!   off; the caller's reference: g0 when it was measured still, then |f| at
//!   each rest; without one, within `UNANCHORED_BAND` of 1 g), and the low-passed,
//!   bias-corrected rate under `rate_dps` plus three bias sigmas on every
//!   axis (a steady turn is steady too; before the bias is known this test is
//!   necessarily loose);
//! - the low-passed specific force must not move by more than `drift_g`
//!   from where it was when the conditions began: a car that creeps away
//!   from a stop (or reverses) at a smooth, vibration-free 0.09 g is not
//!   standing any more, although each sample on its own looks quiet;
//! - all of it for `min_s` seconds without a break.
//!
//! The deviations' mean squares are held under `DEV_MEMORY` times their
//! thresholds: after a hard 40 deg/s swing the rest is found 3.1 s after
//! its end (the low-passes settling, then `min_s`), not 4.8 s.
//!
//! A part sampled faster than about 300 Hz is averaged in blocks down to
//! about 204.8 Hz first (`BLOCK_HZ`): the deviations then measure the same
//! bandwidth on every part.
//!
//! No allocation, O(1) per sample.

/// Without a measured gravity reference (powered on while moving: g0 then
/// holds the car's acceleration), |f| at rest must be within this of 1 g:
/// loose enough for an accelerometer 1-2 % off scale (a phone), tight
/// enough to refuse a steady 0.25 g acceleration.
pub const UNANCHORED_BAND: f64 = 0.03;

/// The low-passed mean square deviations are held at most this many times
/// their thresholds squared (and start there). Beyond it they would only
/// say how hard the unit moved, which is not when it stopped: after a
/// hand's 40 deg/s swing the unbounded mean square took 3.9 s to fall under
/// `gyro_dev_dps` (`tau_s` ln 2,200); from 4 times the threshold it takes
/// `tau_s` ln 4 = 0.7 s once the deviations have ended.
pub const DEV_MEMORY: f64 = 4.0;

/// The detector's rate, Hz: the samples are averaged in blocks of
/// `round(rate / BLOCK_HZ)` (at least one) before it, so a part sampled
/// faster than about 300 Hz is seen at about this rate (the ADIS16448's
/// 204.8 Hz, the 286-Hz and the 104-Hz recordings: blocks of one). White noise's RMS
/// grows with the square root of the bandwidth: the simulator's ADIS16448
/// noise density at 2 kHz is 0.74 deg/s over three axes sample by sample,
/// over `[rest] gyro_dev_dps` 0.6, and no standstill was ever found; in
/// blocks of ten it is 0.24, as at 204.8 Hz.
pub const BLOCK_HZ: f64 = 204.8;

/// Thresholds of the detector (`[rest]` in the config).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestParams {
    pub tau_s: f64,
    pub min_s: f64,
    pub gyro_dev: f64,
    pub accel_dev: f64,
    pub band: f64,
    pub rate: f64,
    pub drift: f64,
}

impl RestParams {
    /// The detector's thresholds from `[rest]`, rates in rad/s (the
    /// estimator's unit).
    pub fn from_config(r: &crate::config::RestConfig) -> RestParams {
        const D2R: f64 = std::f64::consts::PI / 180.0;
        RestParams {
            tau_s: r.tau_s,
            min_s: r.min_s,
            gyro_dev: r.gyro_dev_dps * D2R,
            accel_dev: r.accel_dev_g,
            band: r.band,
            rate: r.rate_dps * D2R,
            drift: r.drift_g,
        }
    }
}

#[derive(Clone, Debug)]
pub struct RestDetector {
    p: RestParams,
    started: bool,
    gyro_lp: [f64; 3],
    accel_lp: [f64; 3],
    gyro_var: f64,
    accel_var: f64,
    /// Seconds the conditions have held without a break.
    held: f64,
    /// The low-passed specific force when they began.
    anchor: [f64; 3],
    /// The low-pass gain for the step length `alpha_dt`.
    alpha_dt: f64,
    alpha: f64,
    /// Samples averaged into one detector step (`BLOCK_HZ`), for the step
    /// length `block_dt`; the sums and count of the block being filled;
    /// what the last full block said.
    block: u32,
    block_dt: f64,
    sum_gyro: [f64; 3],
    sum_accel: [f64; 3],
    filled: u32,
    last: Option<RestState>,
}

/// What the detector says after one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RestState {
    /// At rest (the conditions have held for `min_s`).
    pub rest: bool,
    /// The conditions hold now (maybe not for `min_s` yet).
    pub quiet: bool,
    /// The signals are steady (the deviation tests alone, without the band,
    /// the rate and the drift tests).
    pub steady: bool,
    /// Low-passed gyro (same unit as the input).
    pub gyro_lp: [f64; 3],
    /// Low-passed specific force, g.
    pub accel_lp: [f64; 3],
    /// Mean square deviation of the gyro from its low-pass (input unit squared, summed over axes).
    pub gyro_var: f64,
    /// Mean square deviation of the specific force from its low-pass, g^2 (summed over axes).
    pub accel_var: f64,
}

impl RestDetector {
    /// `gyro_dev` and `rate` in the gyro input's unit (rad/s in the estimator).
    pub fn new(p: RestParams) -> RestDetector {
        RestDetector {
            p,
            started: false,
            gyro_lp: [0.0; 3],
            accel_lp: [0.0; 3],
            gyro_var: 0.0,
            accel_var: 0.0,
            held: 0.0,
            anchor: [0.0; 3],
            alpha_dt: -1.0,
            alpha: 0.0,
            block: 1,
            block_dt: -1.0,
            sum_gyro: [0.0; 3],
            sum_accel: [0.0; 3],
            filled: 0,
            last: None,
        }
    }

    /// Forget everything (after a resync).
    pub fn reset(&mut self) {
        self.started = false;
        self.held = 0.0;
        self.filled = 0;
        self.last = None;
    }

    /// Seconds the rest conditions have held.
    pub fn held(&self) -> f64 {
        self.held
    }

    /// One sample: gyro, specific force (g), time step (s), gravity's size as
    /// this unit measures it (g; None: not measured yet), the current bias
    /// estimate and its 1-sigma per axis (gyro unit).
    ///
    /// A part sampled faster than `BLOCK_HZ` is averaged in blocks down to
    /// about that rate first (the state returned between blocks is the last
    /// block's): the deviations then measure the same bandwidth on every
    /// part, and `[rest]`'s thresholds mean the same on a 2-kHz part as on a
    /// 204.8-Hz one.
    pub fn push(
        &mut self,
        gyro: &[f64; 3],
        accel: &[f64; 3],
        dt: f64,
        g_ref: Option<f64>,
        bias: &[f64; 3],
        bias_sigma: [f64; 3],
    ) -> RestState {
        if dt != self.block_dt {
            self.block_dt = dt;
            self.block = ((1.0 / (dt * BLOCK_HZ)).round() as u32).max(1);
            self.filled = 0;
        }
        // the first sample (and the first after a reset) on its own
        let Some(last) = self.last.filter(|_| self.block > 1) else {
            let st = self.step(gyro, accel, dt, g_ref, bias, bias_sigma);
            if self.block > 1 {
                self.last = Some(st);
                self.filled = 0;
            }
            return st;
        };
        for k in 0..3 {
            self.sum_gyro[k] = if self.filled == 0 { gyro[k] } else { self.sum_gyro[k] + gyro[k] };
            self.sum_accel[k] = if self.filled == 0 { accel[k] } else { self.sum_accel[k] + accel[k] };
        }
        self.filled += 1;
        if self.filled < self.block {
            return last;
        }
        let n = self.filled as f64;
        let (g, a) = (self.sum_gyro.map(|v| v / n), self.sum_accel.map(|v| v / n));
        let st = self.step(&g, &a, dt * n, g_ref, bias, bias_sigma);
        self.filled = 0;
        self.last = Some(st);
        st
    }

    /// One detector step on one (block-averaged) sample of length `dt`.
    fn step(&mut self, gyro: &[f64; 3], accel: &[f64; 3], dt: f64, g_ref: Option<f64>, bias: &[f64; 3], bias_sigma: [f64; 3]) -> RestState {
        if !self.started {
            self.gyro_lp = *gyro;
            self.accel_lp = *accel;
            self.gyro_var = self.p.gyro_dev * self.p.gyro_dev * DEV_MEMORY;
            self.accel_var = self.p.accel_dev * self.p.accel_dev * DEV_MEMORY;
            self.started = true;
            self.held = 0.0;
        }
        if dt != self.alpha_dt {
            self.alpha_dt = dt;
            self.alpha = (dt / self.p.tau_s).min(1.0);
        }
        let a = self.alpha;
        let mut dg = 0.0;
        let mut da = 0.0;
        for k in 0..3 {
            self.gyro_lp[k] += (gyro[k] - self.gyro_lp[k]) * a;
            self.accel_lp[k] += (accel[k] - self.accel_lp[k]) * a;
            let eg = gyro[k] - self.gyro_lp[k];
            let ea = accel[k] - self.accel_lp[k];
            dg += eg * eg;
            da += ea * ea;
        }
        self.gyro_var += (dg - self.gyro_var) * a;
        self.accel_var += (da - self.accel_var) * a;
        let gd = self.p.gyro_dev;
        let ad = self.p.accel_dev;
        // how hard the unit moved says nothing about when it stopped: the
        // deviations remember at most DEV_MEMORY times their thresholds
        self.gyro_var = self.gyro_var.min(DEV_MEMORY * gd * gd);
        self.accel_var = self.accel_var.min(DEV_MEMORY * ad * ad);
        let amag = super::quat::norm(&self.accel_lp);
        // per axis: a bias known on one axis and not on another is common
        let turning = (0..3).any(|i| (self.gyro_lp[i] - bias[i]).abs() > self.p.rate + 3.0 * bias_sigma[i]);
        let steady = self.gyro_var < gd * gd && self.accel_var < ad * ad;
        let level = match g_ref {
            Some(g) => (amag / g - 1.0).abs() < self.p.band,
            None => (amag - 1.0).abs() < UNANCHORED_BAND,
        };
        let mut quiet = steady && level && !turning;
        if quiet && self.held == 0.0 {
            self.anchor = self.accel_lp;
        }
        if quiet {
            let d = [self.accel_lp[0] - self.anchor[0], self.accel_lp[1] - self.anchor[1], self.accel_lp[2] - self.anchor[2]];
            quiet = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < self.p.drift * self.p.drift;
        }
        self.held = if quiet { self.held + dt } else { 0.0 };
        RestState {
            rest: self.held >= self.p.min_s,
            quiet,
            steady,
            gyro_lp: self.gyro_lp,
            accel_lp: self.accel_lp,
            gyro_var: self.gyro_var,
            accel_var: self.accel_var,
        }
    }
}

/// Seconds of rest whose mean |f| becomes gravity's reference.
pub const G_REST_S: f64 = 3.0;

/// Gravity's size as this unit measures it, the detector's `g_ref`: g0 (the
/// mean |f| over the first `g0_window_s`) only if the signals were steady all
/// through that window (powered on while driving, g0 holds the car's
/// acceleration), then the mean |f| over the rests once they add up to
/// `G_REST_S` (one short false rest must not set it); None until either.
/// The estimator and `gyrocomp align` both keep one.
#[derive(Clone, Debug)]
pub struct GravityRef {
    value: Option<f64>,
    steady: bool,
    decided: bool,
    /// Sum of |f| dt and of dt over the rests.
    rest_sum: f64,
    rest_s: f64,
}

impl Default for GravityRef {
    fn default() -> Self {
        GravityRef { value: None, steady: true, decided: false, rest_sum: 0.0, rest_s: 0.0 }
    }
}

impl GravityRef {
    /// The reference for the next sample's detector push.
    pub fn get(&self) -> Option<f64> {
        self.value
    }

    /// After the detector's push (`None`: the sample was suspect and not
    /// pushed): `t` seconds since the first sample, `g0` the mean |f| so far,
    /// `window_s` g0's window, `dt` the step.
    pub fn observe(&mut self, st: Option<&RestState>, t: f64, g0: f64, window_s: f64, dt: f64) {
        if !self.decided {
            self.steady &= st.is_some_and(|r| r.steady);
            if t >= window_s {
                self.decided = true;
                if self.steady {
                    self.value = Some(g0);
                }
            }
        }
        if let Some(r) = st.filter(|r| r.rest) {
            self.rest_sum += super::quat::norm(&r.accel_lp) * dt;
            self.rest_s += dt;
            if self.rest_s >= G_REST_S {
                self.value = Some(self.rest_sum / self.rest_s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params() -> RestParams {
        RestParams { tau_s: 0.5, min_s: 1.0, gyro_dev: 0.01, accel_dev: 0.02, band: 0.01, rate: 0.02, drift: 0.01 }
    }

    /// Deterministic pseudo-noise in [-1, 1].
    fn noise(k: u64) -> f64 {
        let x = (k.wrapping_mul(0x9E3779B97F4A7C15) >> 11) as f64 / (1u64 << 53) as f64;
        2.0 * x - 1.0
    }

    /// Seconds until rest is declared for a unit lying still, sampled at
    /// `rate_hz` with the ADIS16448's white noise density (0.0135
    /// deg/s/sqrt(Hz) per axis; uniform noise of that RMS), `[rest]` at its
    /// defaults; None within 10 s.
    fn still_unit_at(rate_hz: f64) -> Option<f64> {
        let d2r = std::f64::consts::PI / 180.0;
        let p = RestParams::from_config(&crate::config::RestConfig::default());
        let mut d = RestDetector::new(p);
        let dt = 1.0 / rate_hz;
        // uniform in [-a, a] has RMS a / sqrt(3)
        let a = 0.0135 * (rate_hz / 2.0).sqrt() * 3f64.sqrt() * d2r;
        let fa = 0.00023 * (rate_hz / 2.0).sqrt() * 3f64.sqrt();
        for k in 0..(10.0 * rate_hz) as u64 {
            let g = [a * noise(6 * k), a * noise(6 * k + 1), a * noise(6 * k + 2)];
            let f = [fa * noise(6 * k + 3), fa * noise(6 * k + 4), -1.0 + fa * noise(6 * k + 5)];
            if d.push(&g, &f, dt, Some(1.0), &[0.0; 3], [1e-3; 3]).rest {
                return Some(k as f64 * dt);
            }
        }
        None
    }

    #[test]
    fn a_still_unit_rests_at_any_sample_rate() {
        // sample by sample the gyro's RMS deviation grows with the rate: at
        // 2 kHz 0.74 deg/s over three axes, over `gyro_dev_dps` 0.6; averaged
        // in blocks down to about 204.8 Hz it is what a 204.8-Hz part sees
        for hz in [104.0, 204.8, 286.0, 819.2, 2000.0] {
            let t = still_unit_at(hz);
            println!("{hz} Hz: rest after {t:?} s");
            let t = t.unwrap_or_else(|| panic!("a still unit sampled at {hz} Hz never rests"));
            assert!(t < 3.0, "{hz} Hz: rest only after {t} s");
        }
    }

    #[test]
    fn blocks_are_only_for_fast_parts_and_keep_the_state_between() {
        let p = RestParams::from_config(&crate::config::RestConfig::default());
        for (hz, block) in [(104.0, 1), (204.8, 1), (286.0, 1), (819.2, 4), (2000.0, 10)] {
            let mut d = RestDetector::new(p);
            let a = d.push(&[0.0; 3], &[0.0, 0.0, -1.0], 1.0 / hz, Some(1.0), &[0.0; 3], [1e-3; 3]);
            assert_eq!(d.block, block, "{hz} Hz");
            // between blocks the last block's state, exactly
            if block > 1 {
                for _ in 0..block - 1 {
                    let b = d.push(&[0.1, 0.0, 0.0], &[0.0, 0.0, -1.0], 1.0 / hz, Some(1.0), &[0.0; 3], [1e-3; 3]);
                    assert_eq!(a, b);
                }
                let c = d.push(&[0.1, 0.0, 0.0], &[0.0, 0.0, -1.0], 1.0 / hz, Some(1.0), &[0.0; 3], [1e-3; 3]);
                assert!(c.gyro_lp[0] > 0.0, "the block's mean was not stepped: {c:?}");
            }
        }
    }

    /// The first time rest is declared after `swing_s` of a hand's hard
    /// swing (40 deg/s and 0.5 g at 1 Hz) has ended, s.
    fn rest_after_swing(swing_s: f64) -> Option<f64> {
        let d2r = std::f64::consts::PI / 180.0;
        let p = RestParams { tau_s: 0.5, min_s: 1.0, gyro_dev: 0.6 * d2r, accel_dev: 0.05, band: 0.005, rate: 0.5 * d2r, drift: 0.01 };
        let mut d = RestDetector::new(p);
        let dt = 0.005;
        let w = 2.0 * std::f64::consts::PI;
        let mut t = 0.0;
        while t < swing_s + 10.0 {
            let s = if t < swing_s { (w * t).sin() } else { 0.0 };
            let st = d.push(&[40.0 * d2r * s, 0.0, 0.0], &[0.0, 0.5 * s, -1.0], dt, Some(1.0), &[0.0; 3], [1e-3; 3]);
            if t >= swing_s && st.rest {
                return Some(t - swing_s);
            }
            t += dt;
        }
        None
    }

    #[test]
    fn a_hard_swing_that_ends_is_rest_within_three_and_a_half_seconds() {
        // 3.1 s: the low-passes settling, then min_s. With the mean squares
        // unbounded it was 4.8 s: the swing's 800 (deg/s)^2 against the
        // threshold's 0.36 alone takes tau ln 2,200 = 3.9 s to forget.
        let after = rest_after_swing(10.0).expect("the unit comes to rest");
        println!("rest {after:.2} s after a 40 deg/s swing ended");
        assert!(after <= 3.5, "rest {after:.2} s after the swing");
        assert!(after >= 1.0, "rest before min_s: {after:.2} s");
        // a longer swing is no slower to forget
        let long = rest_after_swing(60.0).unwrap();
        assert!((long - after).abs() < 0.05, "{long} against {after}");
    }

    #[test]
    fn rest_with_a_large_bias_and_vibration_is_rest_moving_is_not() {
        let mut d = RestDetector::new(params());
        let dt = 0.005;
        let bias = [0.08, -0.05, 0.07]; // rad/s: about 4.6, 2.9, 4.0 deg/s
        let mut st = None;
        for k in 0..400u64 {
            // idle vibration: 0.005 g and 0.003 rad/s of noise on a level unit
            let g = [bias[0] + 0.003 * noise(3 * k), bias[1] + 0.003 * noise(3 * k + 1), bias[2] + 0.003 * noise(3 * k + 2)];
            let a = [0.005 * noise(7 * k), 0.005 * noise(7 * k + 1), -1.0 + 0.005 * noise(7 * k + 2)];
            // the bias is not known yet: sigma 0.1 rad/s
            st = Some(d.push(&g, &a, dt, Some(1.0), &[0.0; 3], [0.1; 3]));
        }
        assert!(st.unwrap().rest, "a resting unit with a large bias is at rest");
        // driving: road vibration 0.1 g
        let mut moving = false;
        for k in 0..200u64 {
            let a = [0.1 * noise(5 * k), 0.1 * noise(5 * k + 1), -1.0 + 0.1 * noise(5 * k + 2)];
            moving |= !d.push(&bias, &a, dt, Some(1.0), &bias, [0.001; 3]).rest;
        }
        assert!(moving);
        assert_eq!(d.held(), 0.0);
    }

    #[test]
    fn a_steady_acceleration_or_turn_is_not_rest_once_the_bias_is_known() {
        let dt = 0.005;
        // a steady 0.2 g forward acceleration: |f| is 2 % above g0
        let mut d = RestDetector::new(params());
        let mut any = false;
        for _ in 0..600 {
            any |= d.push(&[0.0; 3], &[0.2, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.001; 3]).rest;
        }
        assert!(!any, "a steady 0.2 g acceleration was taken for rest");
        // a steady 3 deg/s turn with the bias known to 0.001 rad/s
        let mut d = RestDetector::new(params());
        let mut any = false;
        for _ in 0..600 {
            any |= d.push(&[0.0, 0.0, 0.052], &[0.0, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.001; 3]).rest;
        }
        assert!(!any, "a steady turn was taken for rest");
        // the same turn rate as an unknown bias is rest
        let mut d = RestDetector::new(params());
        let mut last = false;
        for _ in 0..600 {
            last = d.push(&[0.0, 0.0, 0.052], &[0.0, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.1; 3]).rest;
        }
        assert!(last);
    }

    #[test]
    fn creeping_away_from_a_stop_ends_the_rest() {
        // Standing, then a smooth reverse at 0.09 g with no vibration: |f|
        // changes by 0.4 %, inside the band, but f turns by 5 deg.
        let mut d = RestDetector::new(params());
        let dt = 0.005;
        for _ in 0..600 {
            assert!(!d.push(&[0.0; 3], &[0.0, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.001; 3]).rest || d.held() > 0.0);
        }
        assert!(d.push(&[0.0; 3], &[0.0, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.001; 3]).rest);
        let mut ended = None;
        for k in 0..400 {
            let a = -0.09 * (k as f64 / 100.0).min(1.0);
            if !d.push(&[0.0; 3], &[a, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.001; 3]).rest && ended.is_none() {
                ended = Some(k);
            }
        }
        let k = ended.expect("still at rest while reversing");
        assert!(k < 150, "the rest ended only after {k} samples");
    }

    #[test]
    fn needs_min_s_without_a_break() {
        let mut d = RestDetector::new(params());
        let dt = 0.01;
        let mut first = None;
        for k in 0..300 {
            let s = d.push(&[0.0; 3], &[0.0, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.0; 3]);
            if s.rest && first.is_none() {
                first = Some(k);
            }
        }
        // the initial deviation estimate decays first, then 1 s must pass
        let k = first.expect("rest detected");
        assert!(k >= 100, "rest after {k} samples, before min_s");
        // one jolt restarts the clock
        d.push(&[0.5, 0.0, 0.0], &[0.3, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.0; 3]);
        assert!(!d.push(&[0.0; 3], &[0.0, 0.0, -1.0], dt, Some(1.0), &[0.0; 3], [0.0; 3]).rest);
    }

    #[test]
    fn without_a_gravity_reference_the_band_is_about_one_g() {
        // a phone's accelerometer reads 0.988 g at rest: a rest without a
        // reference (g0 measured while driving), outside the 0.5 % band of a
        // reference of 1.011 g, and a steady 0.3 g is never one
        let dt = 1.0 / 200.0;
        let still = |g_ref: Option<f64>, f: [f64; 3]| {
            let mut d = RestDetector::new(params());
            let mut any = false;
            for _ in 0..600 {
                any |= d.push(&[0.0; 3], &f, dt, g_ref, &[0.0; 3], [0.001; 3]).rest;
            }
            any
        };
        assert!(still(None, [0.0, 0.0, -0.988]));
        assert!(!still(Some(1.011), [0.0, 0.0, -0.988]));
        assert!(still(Some(0.988), [0.0, 0.0, -0.988]));
        assert!(!still(None, [0.3, 0.0, -1.0]));
    }
}
