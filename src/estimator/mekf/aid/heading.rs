//! The magnetic heading: the magnetometer's field, turned into the
//! navigation frame, gives the heading (only `dθ_z` and the bias are
//! corrected, never the tilt), gated by a disturbance test on the field's
//! norm and dip against a reference taken at the start.

use crate::estimator::mekf::*;

/// The source's own state.
#[derive(Clone, Debug, Default)]
pub(in crate::estimator::mekf) struct HeadingAid {
    /// The field's reference: norm (gauss) and dip (rad).
    reference: Option<(f64, f64)>,
    /// The reference was taken before the tilt was anchored.
    weak: bool,
    /// Seconds the heading update has been refused without a break.
    refused_s: f64,
    /// Seconds the field has been disturbed without a break.
    disturbed_s: f64,
    /// The heading the car turned to over a gap is not known yet: the next
    /// heading turns the whole state to it (`turn_heading`).
    open: bool,
}

impl HeadingAid {
    /// The reference is taken again from the next field (the tilt it was
    /// measured with was wrong).
    pub fn forget(&mut self) {
        self.reference = None;
    }

    /// Whether the reference was taken before the tilt was anchored.
    pub fn weak(&self) -> bool {
        self.weak
    }

    /// The car turned over a gap: its next heading is taken whole.
    pub fn set_open(&mut self, on: bool) {
        self.open = on;
    }

    #[cfg(test)]
    pub fn is_open(&self) -> bool {
        self.open
    }
}

impl Mekf {
    /// Heading from the magnetometer (`m`, the tick's mean field, body,
    /// gauss). Returns its status; not applicable with `FieldDisturbed`
    /// when the field's norm or dip is off the reference.
    pub(in crate::estimator::mekf) fn fuse_heading(&mut self, m: &[f64; 3], at_rest: bool, learn: bool, gate: f64) -> AidStatus {
        let s = self.heading_update(m, at_rest, learn, gate);
        self.aid.set(Aid::Heading, s);
        s
    }

    fn heading_update(&mut self, m: &[f64; 3], at_rest: bool, learn: bool, gate: f64) -> AidStatus {
        if self.heading.open {
            // the tick's corrections so far are in the frame a turn would leave
            self.inject();
        }
        let mn = rotate(self.core.c(), m);
        let nrm = norm(&mn);
        let h2 = mn[0] * mn[0] + mn[1] * mn[1];
        if nrm < 1e-6 || h2 < 1e-12 {
            return AidStatus::NotApplicable(Why::Unobservable);
        }
        let dip = quat::atan2(mn[2], h2.sqrt());
        if !self.field_undisturbed(nrm, dip, at_rest) {
            return AidStatus::NotApplicable(Why::FieldDisturbed);
        }
        let psi = quat::atan2(mn[1], mn[0]);
        let nu = wrap_pi(psi - self.p.declination);
        if self.heading.open {
            // The car turned over a gap: take the field's heading whole, the
            // velocity turning with it, then fuse it as usual.
            self.turn_heading(-nu);
            self.counters.rules.note(Rule::GapHeadingOpen);
            self.heading.open = false;
            return self.heading_update(m, at_rest, learn, gate);
        }
        let mut h = [0.0; N];
        h[TH] = mn[0] * mn[2] / h2;
        h[TH + 1] = mn[1] * mn[2] / h2;
        h[TH + 2] = -1.0;
        let u = self.update(&h, nu, self.p.yaw_var, Gain { tilt: false, heading: true, bias: learn, scored: false }, gate);
        // an undisturbed field refused for long: the heading, not the field,
        // is wrong (it was set with a wrong tilt, or drifted with a wrong z
        // bias); open it to what the field says, never a lock-out
        if u.is_refused() {
            self.heading.refused_s += self.p.tick_s;
            if self.heading.refused_s >= HEADING_REACQUIRE_S && self.on(Rule::HeadingReacquire) {
                self.core.floor_var(TH + 2, nu * nu);
                self.heading.refused_s = 0.0;
                self.counters.reacquired += 1;
                self.counters.rules.note(Rule::HeadingReacquire);
            }
        } else {
            self.heading.refused_s = 0.0;
        }
        u
    }

    /// The field's norm `nrm` (gauss) and dip (rad) against the reference
    /// (taken now when there is none): whether the field is undisturbed.
    /// The dip is measured with the filter's tilt: a reference taken before
    /// a standstill or a saved bias anchored that tilt (powered on while
    /// driving) is taken again once one has (`mag_ref_retake`); a field
    /// that stays different for a minute and is steady at a rest is the new
    /// normal (moved car, new mounting: `mag_new_normal`).
    fn field_undisturbed(&mut self, nrm: f64, dip: f64, at_rest: bool) -> bool {
        if self.bias_known && self.heading.weak && self.on(Rule::MagRefRetake) {
            self.counters.rules.note(Rule::MagRefRetake);
            self.heading.reference = None;
        }
        if self.heading.reference.is_none() {
            self.heading.weak = !self.bias_known;
        }
        let Some((rn, rd)) = self.heading.reference else {
            // no reference (yet, or again): the field as it is now
            self.heading.reference = Some((nrm, dip));
            self.heading.disturbed_s = 0.0;
            return true;
        };
        let disturbed = ((nrm / rn) - 1.0).abs() > self.p.mag_norm_tol || (dip - rd).abs() > self.p.mag_dip_tol;
        if !disturbed {
            self.heading.disturbed_s = 0.0;
            return true;
        }
        self.heading.disturbed_s += self.p.tick_s;
        if at_rest && self.heading.disturbed_s > 60.0 && self.on(Rule::MagNewNormal) {
            self.counters.rules.note(Rule::MagNewNormal);
            self.heading.reference = Some((nrm, dip));
            self.heading.disturbed_s = 0.0;
        }
        false
    }
}
