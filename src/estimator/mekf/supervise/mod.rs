//! Recovery, as named rules (`rules.rs`): re-levelling a tilt the data
//! keep refusing, re-acquiring a velocity or a heading refused for long,
//! restarting a diverged filter from its prior, and what a counter gap
//! leaves unknown. The power-on speed hypotheses are the facade's bank
//! (`estimator::hypotheses`).

mod gap;
mod recover;
mod relevel;
