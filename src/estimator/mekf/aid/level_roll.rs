//! The level roll: a car's body is level in roll to within
//! `LEVEL_ROLL_SIGMA`.

use crate::estimator::mekf::*;

impl Mekf {
    /// The road's crossfall and a curve's superelevation, the body's lean in
    /// a turn, a unit mounted a degree or two off its `[mounting]`: within
    /// `LEVEL_ROLL_SIGMA`. Without a heading reference (no magnetometer in
    /// use) and before a standstill has read the bias, nothing else tells
    /// the roll from the yaw-rate bias: the vehicle constraint sees only
    /// their sum in the lateral acceleration, `u δb_z = g δφ` at speed `u`.
    /// The filter then settled wherever the speed's changes happened to put
    /// it, confident and wrong (the comma2k19 car without its magnetometer:
    /// z bias 1.1 deg/s against about 3.9 with a 1-sigma of 0.2, roll 5-7
    /// deg off). Once per level window, with the car's axes in use; never
    /// gated.
    pub(in crate::estimator::mekf) fn fuse_level_roll(&mut self, gain: Gain) {
        let row = if self.on(Rule::LevelRoll) { self.car_roll_row() } else { None };
        let s = match row {
            Some((roll, h)) => {
                let s = self.update(&h, -roll, LEVEL_ROLL_SIGMA * LEVEL_ROLL_SIGMA, gain, f64::INFINITY);
                self.counters.rules.note(Rule::LevelRoll);
                s
            }
            None if !self.on(Rule::LevelRoll) => AidStatus::NotApplicable(Why::RuleOff),
            None => AidStatus::NotApplicable(Why::Unobservable),
        };
        self.aid.set(Aid::LevelRoll, s);
    }

    /// The car's roll (its axes in use) and its row of H; None on its side.
    pub(in crate::estimator::mekf) fn car_roll_row(&self) -> Option<(f64, [f64; N])> {
        // gravity's direction in the car's y and z axes
        let wy = rotate(self.core.c(), &self.axes.rows[1]);
        let wz = rotate(self.core.c(), &self.axes.rows[2]);
        let (gy, gz) = (wy[2], wz[2]);
        let n2 = gy * gy + gz * gz;
        if n2 < 0.25 {
            return None;
        }
        // (C_true a)_z = (C a)_z + dθx (C a)_y - dθy (C a)_x
        let mut h = [0.0; N];
        h[TH] = (gz * wy[1] - gy * wz[1]) / n2;
        h[TH + 1] = (gy * wz[0] - gz * wy[0]) / n2;
        Some((gy.atan2(gz), h))
    }
}
