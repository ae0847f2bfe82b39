//! The default filter's situation rules, named: what the filter does on top
//! of its propagation and its plain measurements because of a situation it
//! recognises. Each has a switch, for ablation only (`[mekf] ablate`,
//! `gyrocomp evaluate --ablate`): with a rule switched off the filter
//! behaves as if the rule had never been written. Every rule is on by
//! default; the default filter is the filter with none switched off.

/// One named rule (a new one needs its row in `RULES`, in this order).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Rule {
    Cruise,
    Accelerating,
    VelocityAge,
    TurningAtSpeed,
    FieldTurned,
    GravityTurned,
    GapVelocityUnknown,
    WheelStanding,
    LevelRate,
    LevelRoll,
    VerticalSpeedBound,
    ForwardSpeedBound,
    QuietVelocityNoise,
    KnockNoise,
    Relevel,
    VelocityReacquire,
    HeadingReacquire,
    RestartLost,
    RestartBiasRange,
    PullAwayAxes,
    SpeedHypotheses,
    FreeUnitCopy,
    LeaveVehicleModel,
    RelevelFree,
    ProvisionalBias,
    GravityLag,
    GapHeadingOpen,
    MagRefRetake,
    MagNewNormal,
}

/// Every rule: its name in the config and the tables, what it does, and
/// where it acts. In the enum's order, which is the ablation table's:
/// `Rule::describe` finds a rule's row by its discriminant, and `Rule::ALL`
/// is this column (checked at compile time below).
const RULES: [(Rule, &str, &str, &str); 29] = [
    (
        Rule::Cruise,
        "cruise",
        "a quiet period whose zero velocity the velocity state refuses (NIS against zero beyond stop_sigma^2) is a smooth cruise, not a stop",
        "mekf/tick.rs, context/velocity_belief.rs",
    ),
    (
        Rule::Accelerating,
        "accelerating",
        "a quiet tick, stop or cruise, whose specific force the held tilt refuses as gravity (the tilt confirmed at a standstill since power-on, a restart or a gap) is an acceleration: a moving tick, its rate not the bias",
        "mekf/tick.rs",
    ),
    (
        Rule::VelocityAge,
        "velocity_age",
        "the velocity ages with the heading turned since the last stop (an accelerometer bias no longer cancels), letting a stop in",
        "mekf/context/velocity_belief.rs",
    ),
    (
        Rule::TurningAtSpeed,
        "turning_at_speed",
        "a still period whose specific force lies along the centripetal acceleration of the filter's motion is a turn",
        "mekf/context/turning.rs",
    ),
    (
        Rule::FieldTurned,
        "field_turned",
        "a still period during which the magnetic field turned in the car's frame is a turn",
        "mekf/context/turning.rs",
    ),
    (
        Rule::GravityTurned,
        "gravity_turned",
        "a quiet period during which gravity turned in the car's frame (a pitch or roll rate a standing car has not) is motion",
        "mekf/context/gravity_turned.rs",
    ),
    (
        Rule::GapVelocityUnknown,
        "gap_velocity_unknown",
        "the first quiet period after a counter gap is judged with the velocity unknown",
        "mekf/tick.rs",
    ),
    (
        Rule::WheelStanding,
        "wheel_standing",
        "with wheel speeds, the wheels decide that the car stands (0.5 s under 0.05 m/s), the IMU only that it is quiet",
        "mekf/tick.rs, aid/wheel_speed.rs",
    ),
    (Rule::LevelRate, "level_rate", "a car before its bias is read: its mean roll/pitch rate over 3 s is its bias's", "mekf/aid/level_rate.rs"),
    (
        Rule::LevelRoll,
        "level_roll",
        "a car with no heading reference before its bias is read: its roll is level within 3 deg",
        "mekf/aid/level_roll.rs",
    ),
    (Rule::VerticalSpeedBound, "vertical_speed_bound", "a car's vertical speed is held within max_vertical_speed", "mekf/aid/vertical_speed.rs"),
    (
        Rule::ForwardSpeedBound,
        "forward_speed_bound",
        "a car's forward speed is held within -max_reverse_speed..max_forward_speed",
        "mekf/aid/forward_speed.rs",
    ),
    (
        Rule::QuietVelocityNoise,
        "quiet_velocity_noise",
        "a quiet car's velocity noise is accel_noise_quiet, rising with its acceleration and vibration (off: accel_noise always)",
        "mekf/kalman.rs",
    ),
    (
        Rule::KnockNoise,
        "knock_noise",
        "a knock (vibration beyond 0.5 g within a tick) opens the velocity far beyond accel_noise",
        "mekf/kalman.rs",
    ),
    (
        Rule::Relevel,
        "relevel",
        "a standstill whose evidence is refused for relevel_s re-levels the tilt, the bias and the velocity",
        "mekf/tick.rs, supervise/relevel.rs",
    ),
    (
        Rule::VelocityReacquire,
        "velocity_reacquire",
        "velocity constraints refused in motion for relevel_s widen the velocity",
        "mekf/supervise/recover.rs",
    ),
    (Rule::HeadingReacquire, "heading_reacquire", "an undisturbed field refused for 5 s opens the heading to it", "mekf/aid/heading.rs"),
    (
        Rule::RestartLost,
        "restart_lost",
        "velocity constraints refused 80 % of the time (over 5 s) restart the filter from its prior",
        "mekf/supervise/recover.rs",
    ),
    (
        Rule::RestartBiasRange,
        "restart_bias_range",
        "a bias beyond 4 prior sigmas before a standstill has read it restarts the filter from its prior",
        "mekf/supervise/recover.rs",
    ),
    (
        Rule::PullAwayAxes,
        "pull_away_axes",
        "pull-aways after still periods turn the vehicle constraint's axes about the body z axis",
        "mekf/forward_axis.rs",
    ),
    (
        Rule::SpeedHypotheses,
        "speed_hypotheses",
        "a car IMU only runs a bank of power-on forward speeds until a standstill every copy takes for one (at most 60 s)",
        "hypotheses.rs",
    ),
    (
        Rule::FreeUnitCopy,
        "free_unit_copy",
        "the power-on bank runs a free-unit copy, published if the unit leaves the vehicle model",
        "hypotheses.rs, mekf/context/motion_model.rs",
    ),
    (
        Rule::LeaveVehicleModel,
        "leave_vehicle_model",
        "vehicle = auto leaves the vehicle model when the roll/pitch rates swing like a hand's or the unit tilts past 45 deg",
        "mekf/context/motion_model.rs",
    ),
    (
        Rule::RelevelFree,
        "relevel_free",
        "a free unit whose low-passed gravity is refused for relevel_s turns its tilt to it",
        "mekf/supervise/relevel.rs",
    ),
    (
        Rule::ProvisionalBias,
        "provisional_bias",
        "a free unit powered on in motion learns its bias in motion once its tilt has settled on the low-passed gravity",
        "mekf/tick.rs",
    ),
    (
        Rule::GravityLag,
        "gravity_lag",
        "the low-passed gravity's lag of a bias error (tau C_lag db) is in its row while the bias is unread",
        "mekf/aid/free_gravity.rs",
    ),
    (
        Rule::GapHeadingOpen,
        "gap_heading_open",
        "after a counter gap, a car's next magnetic heading turns the whole state (attitude and velocity) to it",
        "mekf/supervise/gap.rs, aid/heading.rs",
    ),
    (
        Rule::MagRefRetake,
        "mag_ref_retake",
        "the field's reference taken before the tilt was anchored is taken again once it is",
        "mekf/aid/heading.rs, tick.rs",
    ),
    (
        Rule::MagNewNormal,
        "mag_new_normal",
        "a field disturbed for a minute and steady at a rest becomes the new reference",
        "mekf/aid/heading.rs",
    ),
];

// `Rule::describe` indexes `RULES` by `Rule as usize`: every row must sit
// at its rule's discriminant.
const _: () = {
    let mut i = 0;
    while i < RULES.len() {
        assert!(RULES[i].0 as usize == i, "RULES must list the rules in the enum's order");
        i += 1;
    }
};

impl Rule {
    /// Every rule, in the order of the ablation table (`RULES`' first column).
    pub const ALL: [Rule; RULES.len()] = {
        let mut all = [Rule::Cruise; RULES.len()];
        let mut i = 0;
        while i < all.len() {
            all[i] = RULES[i].0;
            i += 1;
        }
        all
    };

    /// The rule's name in the config and the tables.
    pub fn name(self) -> &'static str {
        self.describe().0
    }

    /// (name, what it does, where).
    pub fn describe(self) -> (&'static str, &'static str, &'static str) {
        let (_, name, what, place) = RULES[self as usize];
        (name, what, place)
    }

    /// The rule of this name.
    pub fn from_name(name: &str) -> Option<Rule> {
        Rule::ALL.iter().copied().find(|r| r.name() == name)
    }

    /// The rule of this name, or an error naming it and listing the rules
    /// (`[mekf] ablate`, `evaluate --rules`).
    pub fn parse(name: &str) -> Result<Rule, String> {
        Rule::from_name(name).ok_or_else(|| {
            let known: Vec<&str> = Rule::ALL.iter().map(|r| r.name()).collect();
            format!("unknown rule {name:?}; the rules are {}", known.join(", "))
        })
    }

    fn bit(self) -> u32 {
        1 << (self as u32)
    }
}

/// How often each rule acted: ticks for a rule that holds a state (a
/// cruise, a turn, the wheels standing), times for one that acts once (a
/// re-level, a bound applied, a restart).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RuleCounts([u64; Rule::ALL.len()]);

impl RuleCounts {
    /// `r` acted once more.
    #[inline]
    pub fn note(&mut self, r: Rule) {
        self.0[r as usize] += 1;
    }

    /// How often `r` acted.
    pub fn get(&self, r: Rule) -> u64 {
        self.0[r as usize]
    }

    /// The rules that acted, with their counts, in table order.
    pub fn acted(&self) -> Vec<(Rule, u64)> {
        Rule::ALL.iter().map(|r| (*r, self.get(*r))).filter(|(_, n)| *n > 0).collect()
    }
}

impl std::fmt::Display for RuleCounts {
    /// "cruise 1200, level_rate 45" (the rules that acted), or "none".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let a = self.acted();
        if a.is_empty() {
            return write!(f, "none");
        }
        let parts: Vec<String> = a.iter().map(|(r, n)| format!("{} {n}", r.name())).collect();
        write!(f, "{}", parts.join(", "))
    }
}

impl serde::Serialize for RuleCounts {
    /// A map of the rules that acted to their counts.
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let a = self.acted();
        let mut m = s.serialize_map(Some(a.len()))?;
        for (r, n) in a {
            m.serialize_entry(r.name(), &n)?;
        }
        m.end()
    }
}

/// The rules switched off (none by default).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RulesOff(u32);

impl RulesOff {
    /// The rules named, or the first unknown name with the known ones.
    pub fn from_names<S: AsRef<str>>(names: &[S]) -> Result<RulesOff, String> {
        let mut off = RulesOff::default();
        for n in names {
            off.0 |= Rule::parse(n.as_ref())?.bit();
        }
        Ok(off)
    }

    /// Only this rule switched off.
    pub fn only(r: Rule) -> RulesOff {
        RulesOff(r.bit())
    }

    /// Whether `r` is on.
    #[inline]
    pub fn on(self, r: Rule) -> bool {
        self.0 & r.bit() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_rule_has_its_own_name_and_bit() {
        let mut names: Vec<&str> = Rule::ALL.iter().map(|r| r.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Rule::ALL.len());
        for r in Rule::ALL {
            assert_eq!(Rule::from_name(r.name()), Some(r));
            let off = RulesOff::only(r);
            assert!(!off.on(r));
            assert_eq!(Rule::ALL.iter().filter(|o| !off.on(**o)).count(), 1, "{}", r.name());
            assert!(RulesOff::default().on(r));
        }
        assert!(RulesOff::from_names(&["cruise", "level_rate"]).is_ok_and(|o| !o.on(Rule::Cruise) && !o.on(Rule::LevelRate)));
        let e = RulesOff::from_names(&["cruse"]).unwrap_err();
        assert!(e.contains("\"cruse\"") && e.contains("cruise"), "{e}");
    }

    #[test]
    fn the_counts_say_which_rules_acted() {
        let mut c = RuleCounts::default();
        assert_eq!(c.to_string(), "none");
        c.note(Rule::LevelRate);
        c.note(Rule::Cruise);
        c.note(Rule::Cruise);
        assert_eq!(c.to_string(), "cruise 2, level_rate 1");
        assert_eq!(c.get(Rule::Relevel), 0);
    }
}
