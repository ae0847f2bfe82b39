//! The plan run backwards: physical channels into frames, for
//! `gyrocomp simulate --input-dbc` (the simulator's bus in a DBC format)
//! and for benchmarks. Not on the decoding path; it may allocate.

use super::extract::{gather, low_bits, Extractor};
use super::plan::{j1850, Assembly, Crc, DbcPlan};

impl Extractor {
    /// Write `raw` (its low `size` bits) into the signal's bits of `d`.
    pub fn put(&self, d: &mut [u8], raw: u64) {
        let (first, bytes, shift) = self.window();
        let w = &mut d[first..first + bytes];
        let mask = u128::from(low_bits(self.size)) << shift;
        let mut v = (gather::<u128>(w, self.motorola) & !mask) | ((u128::from(raw) << shift) & mask);
        // back in the order gather read them: the last byte read holds the low bits
        for i in 0..bytes {
            w[if self.motorola { bytes - 1 - i } else { i }] = v as u8;
            v >>= 8;
        }
    }

    /// The raw value nearest to `x`, saturated at the signal's range (two's complement bits when signed).
    pub fn quantise(&self, x: f64) -> u64 {
        let (lo, hi) = self.raw_range();
        let (lo, hi) = (lo as f64, hi as f64);
        let r = if x.is_finite() { x.round().clamp(lo, hi) } else { 0.0 };
        if r < 0.0 {
            (r as i64) as u64 & low_bits(self.size)
        } else {
            r as u64
        }
    }
}

/// One encoded frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Encoded {
    pub id: u32,
    pub extended: bool,
    pub data: Vec<u8>,
}

impl DbcPlan {
    /// The frames of sample number `k` carrying `vals` (gyro deg/s, accel g,
    /// temp deg C, in [`crate::config::dbcin::CHANNELS`] order): every
    /// channel quantised to its signal, counters `k` modulo their width,
    /// validity signals at their wanted values, CRCs filled in. J1939 IDs
    /// get priority 3.
    pub fn encode(&self, k: u64, vals: &[f64; 7]) -> Vec<Encoded> {
        self.msgs
            .iter()
            .map(|m| {
                let mut d = vec![0u8; m.len];
                for &c in &m.channels {
                    let Some(ch) = &self.channels[c] else { continue };
                    let x = vals[c];
                    let (mag, neg) = match ch.sign {
                        Some(_) => (x.abs(), x < 0.0),
                        None => (x, false),
                    };
                    ch.sig.put(&mut d, ch.sig.quantise((mag - ch.b) / ch.a));
                    if let Some(s) = ch.sign {
                        s.put(&mut d, u64::from(neg));
                    }
                }
                if let (Some(c), Assembly::Counter { modulus }) = (m.counter, self.assembly) {
                    c.put(&mut d, k % u64::from(modulus));
                }
                for (ex, want, _) in &m.valid {
                    ex.put(&mut d, *want);
                }
                if let Some(Crc::J1850 { at }) = m.crc {
                    d[at as usize] = j1850(&d, at as usize);
                }
                let id = if m.extended && m.mask != 0x1FFF_FFFF { m.id | 3 << 26 } else { m.id };
                Encoded { id, extended: m.extended, data: d }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn put_is_the_inverse_of_raw() {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        for len in [8usize, 32] {
            for start in 0..8 * len as u64 {
                for size in [1u64, 3, 8, 10, 14, 16, 32, 64] {
                    for motorola in [false, true] {
                        let Ok(e) = Extractor::new(start, size, motorola, false, len) else { continue };
                        x ^= x << 13;
                        x ^= x >> 7;
                        x ^= x << 17;
                        let raw = if size == 64 { x } else { x & ((1 << size) - 1) };
                        let mut d = vec![0xA5u8; len];
                        let before = d.clone();
                        e.put(&mut d, raw);
                        assert_eq!(e.raw(&d), raw, "start {start} size {size} m {motorola}");
                        // the other bits are untouched
                        let mut back = d.clone();
                        e.put(&mut back, e.raw(&before));
                        assert_eq!(back, before);
                    }
                }
            }
        }
    }
}
