//! Frames into samples by the plan: equal counters, or a time window.

use super::plan::{Assembly, DbcPlan};
use crate::adis::{Drop, InputCounters, Push, RawFrame, Sample, RESYNC_AFTER};
use std::sync::Arc;

/// Assembles samples from the frames of a DBC-described IMU. Holds one
/// sample in progress; allocates nothing per frame.
#[derive(Clone, Debug)]
pub struct DbcAssembler {
    plan: Arc<DbcPlan>,
    /// One bit per message received for the sample in progress, and all of them.
    have: u32,
    full: u32,
    /// Counter of the sample in progress, or the time its window opened (us).
    cur: u64,
    /// Decoded channels of the sample in progress ([`crate::config::dbcin::CHANNELS`] order).
    vals: [f64; 7],
    diag: u16,
    /// Counter (or time, us) of the last accepted sample.
    last: Option<u64>,
    stale_run: u32,
    /// The running sample counter reported as `Sample::cnt`.
    seq: u16,
    pub counters: InputCounters,
}

impl DbcAssembler {
    pub fn new(plan: Arc<DbcPlan>) -> DbcAssembler {
        let full = ((1u64 << plan.msgs.len()) - 1) as u32;
        DbcAssembler {
            plan,
            have: 0,
            full,
            cur: 0,
            vals: [0.0; 7],
            diag: 0,
            last: None,
            stale_run: 0,
            seq: 0,
            counters: InputCounters::default(),
        }
    }

    pub fn plan(&self) -> &DbcPlan {
        &self.plan
    }

    fn drop(&mut self, d: Drop) -> Push {
        self.counters.bump(d);
        Push::Dropped(d)
    }

    /// Push one frame received at `t_us`.
    pub fn push(&mut self, t_us: u64, f: RawFrame<'_>) -> Push {
        self.counters.frames += 1;
        let plan = Arc::clone(&self.plan);
        let Some(mi) = (if f.remote { None } else { plan.find(f.id, f.extended) }) else {
            return self.drop(Drop::UnknownId);
        };
        let m = &plan.msgs[mi];
        if f.data.len() != m.len {
            return self.drop(Drop::WrongDlc);
        }
        if m.crc.is_some_and(|c| !c.ok(f.data)) {
            return self.drop(Drop::Checksum);
        }
        let bit = 1u32 << mi;
        let steps = match plan.assembly {
            Assembly::Counter { modulus } => {
                let cnt = m.counter.map_or(0, |c| c.raw(f.data));
                match self.by_counter(cnt, bit, modulus) {
                    Ok(s) => s,
                    Err(p) => return p,
                }
            }
            Assembly::Window { us } => self.by_window(t_us, bit, us),
        };
        for &k in &m.channels {
            if let Some(c) = &plan.channels[k] {
                self.vals[k] = c.value(f.data);
            }
        }
        for (ex, want, b) in &m.valid {
            if ex.value(f.data) != *want {
                self.diag |= b;
            }
        }
        self.have |= bit;
        if self.have != self.full {
            return Push::Pending;
        }
        let steps = steps(self);
        Push::Sample(self.complete(t_us, steps))
    }

    /// Counter mode: the checks of the ADIS path modulo the counter's width.
    /// Ok: how to count the sample's steps once it is complete.
    fn by_counter(&mut self, cnt: u64, bit: u32, modulus: u32) -> Result<fn(&Self) -> u32, Push> {
        let m = u64::from(modulus);
        if let Some(last) = self.last {
            let d = (cnt + m - last) % m;
            if d == 0 {
                return Err(self.drop(Drop::Duplicate));
            }
            if d >= m / 2 {
                self.stale_run += 1;
                if self.stale_run < RESYNC_AFTER {
                    return Err(self.drop(Drop::OutOfOrder));
                }
                self.counters.resyncs += 1;
                self.last = None;
                self.have = 0;
            }
        }
        self.stale_run = 0;
        if self.have != 0 && cnt != self.cur {
            self.have = 0;
            self.counters.bump(Drop::Partial);
        }
        if self.have & bit != 0 {
            return Err(self.drop(Drop::Duplicate));
        }
        if self.have == 0 {
            self.diag = 0;
        }
        self.cur = cnt;
        Ok(|a: &Self| a.last.map_or(0, |l| ((a.cur + (a.modulus() - l)) % a.modulus()) as u32))
    }

    fn modulus(&self) -> u64 {
        match self.plan.assembly {
            Assembly::Counter { modulus } => u64::from(modulus),
            Assembly::Window { .. } => 1,
        }
    }

    /// Window mode: a message seen twice, or a frame after the window, abandons the sample.
    fn by_window(&mut self, t_us: u64, bit: u32, us: u64) -> fn(&Self) -> u32 {
        if self.have != 0 && (self.have & bit != 0 || t_us.saturating_sub(self.cur) > us) {
            self.have = 0;
            self.counters.bump(Drop::Partial);
        }
        if self.have == 0 {
            self.cur = t_us;
            self.diag = 0;
        }
        // steps from the time since the last sample's window, at the nominal rate
        |a: &Self| {
            a.last.map_or(0, |l| {
                let dt = a.cur.saturating_sub(l) as f64 * 1e-6;
                (dt * a.plan.rate_hz).round().clamp(1.0, f64::from(u16::MAX)) as u32
            })
        }
    }

    fn complete(&mut self, t_us: u64, steps: u32) -> Sample {
        self.have = 0;
        if steps > 1 {
            self.counters.gaps += 1;
            self.counters.lost += u64::from(steps - 1);
        }
        self.seq = if self.last.is_none() { 0 } else { self.seq.wrapping_add(steps as u16) };
        self.last = Some(self.cur);
        self.counters.samples += 1;
        let v = &self.vals;
        let s = Sample {
            cnt: self.seq,
            t_us,
            steps,
            gyro: [v[0], v[1], v[2]],
            accel: [v[3], v[4], v[5]],
            magn: [0.0; 3],
            temp: if self.plan.channels[6].is_some() { v[6] } else { self.plan.temp_default },
            diag: self.diag,
        };
        if s.suspect() {
            self.counters.suspect += 1;
        }
        s
    }
}
