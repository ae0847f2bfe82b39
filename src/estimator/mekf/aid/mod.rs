//! The default filter's aid sources: the measurements it fuses, one file
//! each (as PX4 EKF2 keeps its `aid_sources/`). Each source reports, at
//! every update tick, what it did: fused (with its test ratio), refused by
//! the innovation gate (with its test ratio), or not applicable, and why.
//! The report of the last tick is published (`EST_AID`, the replay
//! summary); the counters keep at how many ticks each source was fused and
//! refused.
//!
//! The test ratio is the normalised innovation squared over the gate
//! (`ν² / (gate · S)`, the largest of the source's rows): above 1 the gate
//! refuses. The bounds (`vertical_speed`, `forward_speed`) and the level
//! roll are never gated: their ratio is reported against the filter's gate
//! all the same, so a large one shows how far the state had run.

use std::fmt;

mod forward_speed;
mod free_gravity;
mod free_velocity;
mod heading;
mod level_rate;
mod level_roll;
mod still_gravity;
mod vehicle_constraint;
mod vertical_speed;
mod wheel_speed;
mod zero_rate;
mod zero_velocity;

pub(super) use free_gravity::FreeGravity;
pub(super) use heading::HeadingAid;
pub(super) use level_rate::LevelWindow;
pub(super) use still_gravity::tilt_innovation;
pub(super) use vehicle_constraint::VelocityRefusals;
pub(super) use wheel_speed::WheelSpeed;

/// One aid source of the default filter (a new one needs its row in
/// `AIDS`, in this order; at most 16 fit the `EST_AID` frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Aid {
    ZeroVelocity,
    ZeroRate,
    StillGravity,
    VehicleConstraint,
    FreeVelocity,
    FreeGravity,
    LevelRate,
    LevelRoll,
    VerticalSpeed,
    ForwardSpeed,
    WheelSpeed,
    Heading,
}

/// Every source: its name and what it measures, in the enum's order (the
/// order of the `EST_AID` frame's 2-bit fields).
const AIDS: [(Aid, &str, &str); 12] = [
    (Aid::ZeroVelocity, "zero_velocity", "at a standstill the velocity is zero"),
    (Aid::ZeroRate, "zero_rate", "still (a standstill or a straight cruise), the gyro reads its bias"),
    (Aid::StillGravity, "still_gravity", "still, the specific force is gravity (roll and pitch)"),
    (Aid::VehicleConstraint, "vehicle_constraint", "a car moving: no lateral and no vertical velocity at the rear axle"),
    (Aid::FreeVelocity, "free_velocity", "a unit that is not a vehicle goes nowhere on average: its velocity is bounded about zero"),
    (Aid::FreeGravity, "free_gravity", "a unit that is not a vehicle: its low-passed specific force is gravity"),
    (Aid::LevelRate, "level_rate", "a car before its bias is read: its mean roll and pitch rate over 3 s is the bias's"),
    (Aid::LevelRoll, "level_roll", "a car with no heading reference before its bias is read: its roll is level within 3 deg"),
    (Aid::VerticalSpeed, "vertical_speed", "a car's vertical speed within max_vertical_speed"),
    (Aid::ForwardSpeed, "forward_speed", "a car's forward speed within -max_reverse_speed..max_forward_speed"),
    (Aid::WheelSpeed, "wheel_speed", "the vehicle's speed from its wheels ([speed])"),
    (Aid::Heading, "heading", "the magnetometer's heading"),
];

const _: () = {
    let mut i = 0;
    while i < AIDS.len() {
        assert!(AIDS[i].0 as usize == i, "AIDS must list the sources in the enum's order");
        i += 1;
    }
    assert!(AIDS.len() <= 16, "EST_AID holds 16 sources");
};

impl Aid {
    /// Every source, in the enum's (and the frame's) order.
    pub const ALL: [Aid; AIDS.len()] = {
        let mut a = [Aid::ZeroVelocity; AIDS.len()];
        let mut i = 0;
        while i < AIDS.len() {
            a[i] = AIDS[i].0;
            i += 1;
        }
        a
    };

    /// The source's name (the summary, the JSON, the DBC's signal).
    pub fn name(self) -> &'static str {
        AIDS[self as usize].1
    }

    /// What the source measures.
    pub fn what(self) -> &'static str {
        AIDS[self as usize].2
    }
}

/// Why a source did not run at a tick.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Why {
    /// The filter has not ticked yet.
    #[default]
    NotStarted,
    /// The tick held a suspect sample (`DIAG_STAT`): nothing is fused.
    Suspect,
    /// A source of a still unit, and the unit moves.
    Moving,
    /// A source of a moving unit, and the unit is still.
    Still,
    /// Still, but a smooth cruise: the velocity refused to stop.
    Cruising,
    /// A car's source, and the unit is not a vehicle.
    NotVehicle,
    /// A free unit's source, and the unit is a vehicle.
    Vehicle,
    /// Only before a standstill has read the bias.
    BiasKnown,
    /// Its window (3 s) is still filling.
    Window,
    /// Its window turned about the vertical.
    Turning,
    /// Not with the magnetometer in use.
    HeadingReference,
    /// The state is inside the bound: nothing to say.
    WithinBound,
    /// No speed configured, or none fresh.
    NoSpeed,
    /// No new speed frame since the last tick.
    NoNewFrame,
    /// At a standstill, the zero velocity says it.
    AtRest,
    /// The magnetometer is not in use.
    NoMagnetometer,
    /// The field's norm or dip is off its reference.
    FieldDisturbed,
    /// The quantity is not observable now (the car on its side, a field
    /// along the vertical, gravity under 0.3 g).
    Unobservable,
    /// Its rule is switched off (`[mekf] ablate`).
    RuleOff,
    /// With wheel speeds, the wheels speak for the speed.
    Wheels,
}

impl Why {
    pub fn as_str(self) -> &'static str {
        match self {
            Why::NotStarted => "not started",
            Why::Suspect => "suspect sample",
            Why::Moving => "moving",
            Why::Still => "still",
            Why::Cruising => "cruising",
            Why::NotVehicle => "not a vehicle",
            Why::Vehicle => "a vehicle",
            Why::BiasKnown => "bias known",
            Why::Window => "window filling",
            Why::Turning => "turning",
            Why::HeadingReference => "heading reference in use",
            Why::WithinBound => "within bound",
            Why::NoSpeed => "no speed",
            Why::NoNewFrame => "no new speed frame",
            Why::AtRest => "at rest",
            Why::NoMagnetometer => "no magnetometer",
            Why::FieldDisturbed => "field disturbed",
            Why::Unobservable => "unobservable",
            Why::RuleOff => "rule off",
            Why::Wheels => "wheels",
        }
    }
}

/// What one source did at a tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AidStatus {
    NotApplicable(Why),
    /// Fused; the largest test ratio of its rows.
    Fused(f64),
    /// The gate refused at least one of its rows; the largest test ratio.
    Refused(f64),
}

impl Default for AidStatus {
    fn default() -> Self {
        AidStatus::NotApplicable(Why::NotStarted)
    }
}

impl AidStatus {
    /// The 2-bit code of the `EST_AID` frame: 0 not applicable, 1 fused,
    /// 2 refused.
    pub fn code(self) -> u32 {
        match self {
            AidStatus::NotApplicable(_) => 0,
            AidStatus::Fused(_) => 1,
            AidStatus::Refused(_) => 2,
        }
    }

    /// The test ratio (0 when not applicable).
    pub fn ratio(self) -> f64 {
        match self {
            AidStatus::NotApplicable(_) => 0.0,
            AidStatus::Fused(r) | AidStatus::Refused(r) => r,
        }
    }

    /// This status and one more row of the same source: refused if either
    /// refused, else fused if either fused (the larger ratio); a row not
    /// applicable leaves it, and a source not applicable so far takes the
    /// row's status whatever it is.
    pub fn and_row(self, o: AidStatus) -> AidStatus {
        let r = self.ratio().max(o.ratio());
        match (self, o) {
            (AidStatus::NotApplicable(_), _) => o,
            (_, AidStatus::NotApplicable(_)) => self,
            (AidStatus::Refused(_), _) | (_, AidStatus::Refused(_)) => AidStatus::Refused(r),
            _ => AidStatus::Fused(r),
        }
    }

    pub fn is_fused(self) -> bool {
        matches!(self, AidStatus::Fused(_))
    }

    pub fn is_refused(self) -> bool {
        matches!(self, AidStatus::Refused(_))
    }
}

impl fmt::Display for AidStatus {
    /// "fused (0.12)", "refused (3.4)", "n/a (moving)".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            AidStatus::NotApplicable(w) => write!(f, "n/a ({})", w.as_str()),
            AidStatus::Fused(r) => write!(f, "fused ({r:.2})"),
            AidStatus::Refused(r) => write!(f, "refused ({r:.2})"),
        }
    }
}

/// The rows of one source at one tick: their combined status, and whether
/// any was fused (a source may fuse some rows and have others refused:
/// what was fused still moved the state).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rows {
    pub status: AidStatus,
    pub any_fused: bool,
}

impl Default for Rows {
    fn default() -> Self {
        Rows { status: AidStatus::NotApplicable(Why::Unobservable), any_fused: false }
    }
}

impl Rows {
    /// One more row.
    pub fn push(&mut self, u: AidStatus) {
        self.any_fused |= u.is_fused();
        self.status = self.status.and_row(u);
    }

    /// These rows and another source's.
    pub fn and(self, o: Rows) -> Rows {
        Rows { status: self.status.and_row(o.status), any_fused: self.any_fused || o.any_fused }
    }

    pub fn refused(&self) -> bool {
        self.status.is_refused()
    }
}

/// What every source did at one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AidReport([AidStatus; Aid::ALL.len()]);

impl AidReport {
    /// A new tick: every source not applicable for `why` until it says
    /// otherwise.
    pub fn all(why: Why) -> AidReport {
        AidReport([AidStatus::NotApplicable(why); Aid::ALL.len()])
    }

    pub fn get(&self, a: Aid) -> AidStatus {
        self.0[a as usize]
    }

    /// Set what `a` did (replacing).
    pub fn set(&mut self, a: Aid, s: AidStatus) {
        self.0[a as usize] = s;
    }

    /// What `a` did, unless it already said so this tick (a still tick
    /// that turned out to be a moving one keeps its sources' statuses).
    pub fn fill(&mut self, a: Aid, s: AidStatus) {
        if self.0[a as usize] == AidStatus::NotApplicable(Why::NotStarted) {
            self.0[a as usize] = s;
        }
    }

    /// The 2-bit codes, source `i` at bits `2i..2i+1` (`EST_AID`).
    pub fn word(&self) -> u32 {
        self.0.iter().enumerate().fold(0, |w, (i, s)| w | s.code() << (2 * i))
    }

    /// The largest test ratio of the tick's sources (fused or refused).
    pub fn worst_ratio(&self) -> f64 {
        self.0.iter().map(|s| s.ratio()).fold(0.0, f64::max)
    }

    /// The packed form an estimate carries.
    pub fn packed(&self) -> AidWord {
        AidWord { status: self.word(), worst_ratio: self.worst_ratio() }
    }
}

impl fmt::Display for AidReport {
    /// "zero_rate fused (0.10), heading refused (2.3), ..." over the sources
    /// that ran.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = Aid::ALL
            .iter()
            .filter(|a| !matches!(self.get(**a), AidStatus::NotApplicable(_)))
            .map(|a| format!("{} {}", a.name(), self.get(*a)))
            .collect();
        if parts.is_empty() {
            return write!(f, "none");
        }
        write!(f, "{}", parts.join(", "))
    }
}

/// What an estimate carries of its tick's aid report: the 2-bit codes
/// (`AidReport::word`) and the largest test ratio. All zero outside the
/// default filter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AidWord {
    pub status: u32,
    pub worst_ratio: f64,
}

impl AidWord {
    /// The status of `a` as its 2-bit code (0 not applicable, 1 fused, 2 refused).
    pub fn code(&self, a: Aid) -> u32 {
        (self.status >> (2 * a as u32)) & 3
    }
}

/// Per source over a run: the update ticks at which it fused, those at
/// which the gate refused it, and the largest test ratio refused.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AidCounts([(u64, u64, f64); Aid::ALL.len()]);

impl AidCounts {
    /// One more tick.
    pub fn add(&mut self, r: &AidReport) {
        for (c, s) in self.0.iter_mut().zip(r.0.iter()) {
            match *s {
                AidStatus::Fused(_) => c.0 += 1,
                AidStatus::Refused(x) => {
                    c.1 += 1;
                    c.2 = c.2.max(x);
                }
                AidStatus::NotApplicable(_) => {}
            }
        }
    }

    /// Ticks fused, ticks refused, and the largest refused test ratio of `a`.
    pub fn get(&self, a: Aid) -> (u64, u64, f64) {
        self.0[a as usize]
    }

    /// The sources that ran at all, in table order.
    pub fn ran(&self) -> Vec<(Aid, (u64, u64, f64))> {
        Aid::ALL.iter().map(|a| (*a, self.get(*a))).filter(|(_, (f, r, _))| *f > 0 || *r > 0).collect()
    }
}

impl fmt::Display for AidCounts {
    /// "zero_rate 1200/3 (worst 9.3), heading 7500/0" over the sources
    /// that ran (ticks fused / refused), or "none".
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let a = self.ran();
        if a.is_empty() {
            return write!(f, "none");
        }
        let parts: Vec<String> = a
            .iter()
            .map(|(a, (fu, re, x))| if *re > 0 { format!("{} {fu}/{re} (worst {x:.1})", a.name()) } else { format!("{} {fu}/0", a.name()) })
            .collect();
        write!(f, "{}", parts.join(", "))
    }
}

impl serde::Serialize for AidCounts {
    /// A map of the sources that ran to {fused, refused, worst_ratio}
    /// (ticks, ticks, the largest refused test ratio).
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        #[derive(serde::Serialize)]
        struct Row {
            fused: u64,
            refused: u64,
            worst_ratio: f64,
        }
        let a = self.ran();
        let mut m = s.serialize_map(Some(a.len()))?;
        for (aid, (fused, refused, worst_ratio)) in a {
            m.serialize_entry(aid.name(), &Row { fused, refused, worst_ratio })?;
        }
        m.end()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_source_has_its_own_name_and_field() {
        let mut names: Vec<&str> = Aid::ALL.iter().map(|a| a.name()).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), Aid::ALL.len());
        let mut r = AidReport::all(Why::Moving);
        for (i, a) in Aid::ALL.iter().enumerate() {
            r.set(*a, if i % 2 == 0 { AidStatus::Fused(0.1) } else { AidStatus::Refused(2.0 + i as f64) });
        }
        let w = r.packed();
        for (i, a) in Aid::ALL.iter().enumerate() {
            assert_eq!(w.code(*a), if i % 2 == 0 { 1 } else { 2 }, "{}", a.name());
        }
        assert_eq!(w.worst_ratio, 2.0 + (Aid::ALL.len() - 1) as f64);
        assert_eq!(AidReport::all(Why::Still).word(), 0);
    }

    #[test]
    fn a_source_with_one_row_refused_is_refused() {
        let mut r = AidReport::all(Why::Moving);
        let mut rows = Rows::default();
        for u in [AidStatus::Fused(0.2), AidStatus::Refused(1.5), AidStatus::Fused(0.1)] {
            rows.push(u);
        }
        assert!(rows.any_fused && rows.refused());
        r.set(Aid::ZeroRate, rows.status);
        assert_eq!(r.get(Aid::ZeroRate), AidStatus::Refused(1.5));
        let mut rows = Rows::default();
        rows.push(AidStatus::NotApplicable(Why::FieldDisturbed));
        r.set(Aid::Heading, rows.status);
        assert_eq!(r.get(Aid::Heading), AidStatus::NotApplicable(Why::FieldDisturbed));
        assert_eq!(r.to_string(), "zero_rate refused (1.50)");
        let mut c = AidCounts::default();
        assert_eq!(c.to_string(), "none");
        c.add(&r);
        r.set(Aid::ZeroRate, AidStatus::Fused(0.3));
        c.add(&r);
        assert_eq!(c.get(Aid::ZeroRate), (1, 1, 1.5));
        assert_eq!(c.to_string(), "zero_rate 1/1 (worst 1.5)");
    }
}
