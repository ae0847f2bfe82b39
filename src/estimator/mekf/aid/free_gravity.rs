//! A free unit's gravity: for a unit that is not a vehicle, the specific
//! force low-passed in the navigation frame (`gravity_lp`) is gravity,
//! held the more loosely the harder the unit is being moved.

use crate::estimator::mekf::*;

/// The source's own state: how long the gravity has been refused, and
/// fused, without a break.
#[derive(Clone, Debug, Default)]
pub(in crate::estimator::mekf) struct FreeGravity {
    /// Seconds refused without a break (`relevel_free` reads it).
    pub refused_s: f64,
    /// Seconds fused without a break since the last start or re-level (0
    /// under the vehicle model, which fuses no such gravity): the tilt has
    /// settled on it after `accel_tau_s` (`settle_free_tilt`).
    pub held_s: f64,
}

impl Mekf {
    /// The navigation-frame low-passed specific force as gravity (tilt
    /// only).
    ///
    /// The low-pass lags by `accel_tau_s` (τ; the Butterworth's delay for
    /// slow changes): it sees the tilt error as it was then. A bias error δb
    /// turns the tilt at `dθ' = -C δb`, so the gravity measures
    /// `dθ(t - τ) = dθ(t) + τ C̄ δb`, `C̄` the attitude low-passed over τ
    /// (`c_lag`). While the filter learns a bias no standstill has read
    /// (provisionally, in motion) that term is in the row: a turn-on bias of
    /// several deg/s puts the lagging tilt a dozen degrees behind, and taken
    /// for a tilt error alone it taught the bias a fraction of what it is.
    /// Once a rest has read the bias, what is left of it is hundredths of a
    /// deg/s (a lag of a tenth of a degree, under the motion's share); the
    /// term then only tied the hand's motion to the bias (broad-05, -18 and
    /// -33 roll RMS up by 0.01-0.04 deg) and is left out.
    pub(in crate::estimator::mekf) fn fuse_free_gravity(&mut self, gain: Gain, gate: f64) -> Rows {
        let (Some(g), Some(nu)) = (self.f_lp, self.gravity_lp_innovation()) else {
            let s = Rows::default();
            self.aid.set(Aid::FreeGravity, s.status);
            return s;
        };
        let var = g.tilt_var(self.p.lp_tilt_var, self.p.tilt_motion_share2);
        let tau = if gain.bias && !self.bias_known && self.on(Rule::GravityLag) { self.p.accel_tau } else { 0.0 };
        let cl = self.c_lag;
        let mut h = [0.0; N];
        h[TH + 1] = 1.0;
        for j in 0..3 {
            h[BI + j] = tau * cl[1][j];
        }
        let a = self.update(&h, nu[0], var, gain, gate);
        let mut h = [0.0; N];
        h[TH] = -1.0;
        for j in 0..3 {
            h[BI + j] = -tau * cl[0][j];
        }
        let b = self.update(&h, nu[1], var, gain, gate);
        let fg = &mut self.free_gravity;
        if a.is_refused() || b.is_refused() {
            fg.refused_s += self.p.tick_s;
            fg.held_s = 0.0;
        } else {
            fg.refused_s = 0.0;
            if a.is_fused() && b.is_fused() {
                fg.held_s += self.p.tick_s;
            }
        }
        let mut s = Rows::default();
        s.push(a);
        s.push(b);
        self.aid.set(Aid::FreeGravity, s.status);
        s
    }

    /// The low-passed gravity's tilt innovation (`tilt_innovation`); None
    /// before there is one, or while it holds less than 0.3 g.
    pub(in crate::estimator::mekf) fn gravity_lp_innovation(&self) -> Option<[f64; 2]> {
        let f = self.f_lp?.gravity;
        let fnm = norm(&f);
        (fnm >= 0.3).then(|| tilt_innovation(&[f[0] / fnm, f[1] / fnm, f[2] / fnm]))
    }
}
