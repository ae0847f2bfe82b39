//! The switching rule of the paper: which information may be fused this sample.
//!
//! `ratio = |a| / g0`, with g0 the |a| measured at power-on.
//! - inner band (default 0.985..1.015): quasi-static, full fusion with bias learning;
//! - between the inner and the outer band (default 0.80..1.20): a weighted blend;
//! - outside the outer band: gyro only (bias from the thermal curve).
//!
//! The acceleration-change ("jerk") criterion. The paper says: "if the slope
//! of the change of acceleration exceeds 20 % of its mean value, the motion is
//! treated as accelerated and no fusion is done". Our exact reading: over a
//! sliding window of `jerk_window_s` seconds the slope is the change of the
//! mean specific-force *vector* between the older and the newer half of the
//! window divided by the time between the halves' centres (g/s); its mean
//! value is the mean |a| over the window (g). The motion counts as
//! accelerated when `slope > jerk_ratio * mean` (both per second, so with the
//! default window the rule reads "a 20 % change of a per second"). Until the
//! window is full the criterion does not fire.

use crate::config::SwitchingConfig;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Band {
    Inner,
    Blend,
    Outside,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decision {
    pub band: Band,
    /// Weight of the accelerometer in the blend: 1 at the inner band's edge,
    /// 0 at the outer band's edge (1 inside the inner band, 0 outside).
    pub weight: f64,
    /// |a| / g0.
    pub ratio: f64,
    /// The acceleration-change criterion fired.
    pub jerk: bool,
}

#[derive(Clone, Debug)]
pub struct Switching {
    inner: [f64; 2],
    outer: [f64; 2],
    /// Ring of the last `n` specific-force vectors and magnitudes.
    ring: Vec<[f64; 4]>,
    head: usize,
    filled: usize,
    /// Running sums: newer half (vector), older half (vector), all magnitudes.
    sum_new: [f64; 3],
    sum_old: [f64; 3],
    sum_mag: f64,
    since_refresh: usize,
    /// jerk_ratio (n/2)^2 dt / n: see `push`.
    jerk_limit: f64,
}

impl Switching {
    pub fn new(c: &SwitchingConfig, rate_hz: f64) -> Switching {
        // an even window of at least 4 samples
        let n = (((c.jerk_window_s * rate_hz).round() as usize).max(4) + 1) & !1;
        Switching {
            inner: c.inner,
            outer: c.outer,
            ring: vec![[0.0; 4]; n],
            head: 0,
            filled: 0,
            sum_new: [0.0; 3],
            sum_old: [0.0; 3],
            sum_mag: 0.0,
            since_refresh: 0,
            jerk_limit: c.jerk_ratio * (n as f64 / 2.0).powi(2) / rate_hz / n as f64,
        }
    }

    /// Forget the acceleration history (after a resync).
    pub fn reset(&mut self) {
        self.filled = 0;
        self.head = 0;
        self.sum_new = [0.0; 3];
        self.sum_old = [0.0; 3];
        self.sum_mag = 0.0;
    }

    /// Band of a ratio, and the blend weight.
    pub fn band(&self, ratio: f64) -> (Band, f64) {
        let [il, ih] = self.inner;
        let [ol, oh] = self.outer;
        if ratio > il && ratio < ih {
            (Band::Inner, 1.0)
        } else if ratio > ol && ratio <= il {
            (Band::Blend, (ratio - ol) / (il - ol))
        } else if ratio >= ih && ratio < oh {
            (Band::Blend, (oh - ratio) / (oh - ih))
        } else {
            (Band::Outside, 0.0)
        }
    }

    /// Add one specific-force sample (g) and decide.
    pub fn classify(&mut self, a: &[f64; 3], g0: f64) -> Decision {
        let mag = super::quat::norm(a);
        let jerk = self.push(a, mag);
        let ratio = mag / g0;
        let (band, weight) = self.band(ratio);
        Decision { band, weight, ratio, jerk }
    }

    fn push(&mut self, a: &[f64; 3], mag: f64) -> bool {
        let n = self.ring.len();
        let h = n / 2;
        // The sample leaving the newer half (n/2 ago) joins the older half;
        // the sample leaving the window (n ago) leaves the older half.
        if self.filled >= h {
            let mi = if self.head >= h { self.head - h } else { self.head + n - h };
            let mid = self.ring[mi];
            for k in 0..3 {
                self.sum_new[k] -= mid[k];
                self.sum_old[k] += mid[k];
            }
        }
        if self.filled >= n {
            let old = self.ring[self.head];
            for k in 0..3 {
                self.sum_old[k] -= old[k];
            }
            self.sum_mag -= old[3];
        }
        self.ring[self.head] = [a[0], a[1], a[2], mag];
        self.head = if self.head + 1 == n { 0 } else { self.head + 1 };
        for k in 0..3 {
            self.sum_new[k] += a[k];
        }
        self.sum_mag += mag;
        self.filled = (self.filled + 1).min(n);
        self.since_refresh += 1;
        if self.since_refresh >= n {
            self.refresh();
        }
        if self.filled < n {
            return false;
        }
        // The change of the mean between the halves is d / (n/2) with
        // d = sum_new - sum_old; the criterion slope = |d| / (n/2)^2 / dt >
        // jerk_ratio * sum_mag / n is compared squared and multiplied out
        // (no sqrt, no division): |d| > jerk_limit * sum_mag.
        let mut d2 = 0.0;
        for k in 0..3 {
            let d = self.sum_new[k] - self.sum_old[k];
            d2 += d * d;
        }
        let limit = self.jerk_limit * self.sum_mag;
        d2 > limit * limit
    }

    /// Recompute the running sums exactly (bounds floating-point drift).
    fn refresh(&mut self) {
        self.since_refresh = 0;
        let n = self.ring.len();
        let h = n / 2;
        self.sum_new = [0.0; 3];
        self.sum_old = [0.0; 3];
        self.sum_mag = 0.0;
        // i = 0 is the newest sample, at head - 1; walk back without a modulo
        let mut j = self.head;
        for i in 0..self.filled {
            j = if j == 0 { n - 1 } else { j - 1 };
            let s = self.ring[j];
            let half = if i < h { &mut self.sum_new } else { &mut self.sum_old };
            for k in 0..3 {
                half[k] += s[k];
            }
            self.sum_mag += s[3];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sw() -> Switching {
        Switching::new(&SwitchingConfig::default(), 100.0)
    }

    #[test]
    fn bands_and_weights() {
        let s = sw();
        assert_eq!(s.band(1.0), (Band::Inner, 1.0));
        assert_eq!(s.band(1.3).0, Band::Outside);
        assert_eq!(s.band(0.79).0, Band::Outside);
        let (b, w) = s.band(1.1075);
        assert_eq!(b, Band::Blend);
        assert!((w - 0.5).abs() < 1e-9);
        let (b, w) = s.band(0.985);
        assert_eq!(b, Band::Blend);
        assert!((w - 1.0).abs() < 1e-9);
    }

    #[test]
    fn jerk_fires_on_fast_change_only() {
        let mut s = sw();
        // steady 1 g: never
        for _ in 0..300 {
            assert!(!s.classify(&[0.0, 0.0, -1.0], 1.0).jerk);
        }
        // a ramp of 0.1 g/s in x: slope 0.1 < 0.2 * ~1.0
        let mut fired = false;
        for k in 0..200 {
            fired |= s.classify(&[0.001 * k as f64, 0.0, -1.0], 1.0).jerk;
        }
        assert!(!fired);
        // a ramp of 0.5 g/s: fires once the window sees it
        let mut s = sw();
        for _ in 0..100 {
            s.classify(&[0.0, 0.0, -1.0], 1.0);
        }
        let mut fired = false;
        for k in 0..100 {
            fired |= s.classify(&[0.005 * k as f64, 0.0, -1.0], 1.0).jerk;
        }
        assert!(fired);
    }

    #[test]
    fn running_sums_match_recomputation() {
        let mut s = sw();
        for k in 0..1037 {
            let x = ((k * 37) % 101) as f64 * 0.01;
            s.classify(&[x, -x * 0.5, -1.0], 1.0);
        }
        let (a, b, m) = (s.sum_new, s.sum_old, s.sum_mag);
        s.refresh();
        for k in 0..3 {
            assert!((a[k] - s.sum_new[k]).abs() < 1e-9);
            assert!((b[k] - s.sum_old[k]).abs() < 1e-9);
        }
        assert!((m - s.sum_mag).abs() < 1e-9);
    }
}
