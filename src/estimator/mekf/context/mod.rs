//! Classifiers of the situation: what the unit is doing, from the
//! measurements and the filter's own belief. Each answers a question the
//! tick asks (is this quiet period a stop, a cruise, a turn, a car rolling
//! over a grade; is this a vehicle at all) and moves no state of the core.

mod gravity_turned;
mod motion_model;
mod turning;
mod velocity_belief;

pub(super) use gravity_turned::GravityWatch;
pub(super) use turning::FieldWatch;
