//! One signal's bits out of a payload: the byte window and shift worked out
//! once, when the plan is built, so a frame costs a few loads and shifts.

use can_dbc::{ByteOrder, Signal, ValueType};

/// Where a signal's bits are and how to read them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Extractor {
    /// First byte of the window (Intel: the least significant byte; Motorola: the most).
    first: u8,
    /// Bytes in the window (1..=9).
    bytes: u8,
    /// Right shift of the window's value (Intel: little-endian window; Motorola: big-endian).
    shift: u8,
    /// Bits in the signal (1..=64).
    pub size: u8,
    pub motorola: bool,
    pub signed: bool,
}

impl Extractor {
    /// The extractor of `s` in a message of `len` bytes, or why there is none.
    pub fn of(s: &Signal, len: usize) -> Result<Extractor, String> {
        Extractor::new(s.start_bit, s.size, s.byte_order == ByteOrder::BigEndian, s.value_type == ValueType::Signed, len)
    }

    /// DBC numbering: start bit = LSB for Intel, MSB for Motorola (byte i, bit j is `8 i + j`).
    pub fn new(start: u64, size: u64, motorola: bool, signed: bool, len: usize) -> Result<Extractor, String> {
        if size == 0 || size > 64 {
            return Err(format!("size {size} bits (want 1..64)"));
        }
        if start >= 8 * len as u64 {
            return Err(format!("starts at bit {start}, outside the message's {len} bytes"));
        }
        let (first, bit) = ((start / 8) as usize, start % 8);
        let (bytes, shift) = if motorola {
            // the MSB at `bit` of byte `first`, then down through the next bytes
            let rest = size.saturating_sub(bit + 1);
            let bytes = 1 + rest.div_ceil(8);
            (bytes, (bytes - 1) * 8 + bit + 1 - size)
        } else {
            ((bit + size).div_ceil(8), bit)
        };
        if first + bytes as usize > len {
            return Err(format!("runs past the end of the message's {len} bytes"));
        }
        Ok(Extractor { first: first as u8, bytes: bytes as u8, shift: shift as u8, size: size as u8, motorola, signed })
    }

    /// The raw bits, unsigned. `d` must hold the message's bytes.
    #[inline]
    pub fn raw(&self, d: &[u8]) -> u64 {
        let w = &d[self.first as usize..self.first as usize + self.bytes as usize];
        // a 9-byte window (a 64-bit signal not on a byte boundary) needs 72 bits
        let v = if self.bytes <= 8 {
            gather::<u64>(w, self.motorola) >> self.shift
        } else {
            (gather::<u128>(w, self.motorola) >> self.shift) as u64
        };
        v & low_bits(self.size)
    }

    /// The raw value as a number, sign-extended when the signal is signed.
    #[inline]
    pub fn value(&self, d: &[u8]) -> i128 {
        let r = self.raw(d);
        if self.signed && (r >> (self.size - 1)) & 1 == 1 {
            (r as i128) - (1i128 << self.size)
        } else {
            r as i128
        }
    }

    /// The raw value as a float (sign-extended when signed), without i128 arithmetic.
    #[inline]
    pub fn value_f64(&self, d: &[u8]) -> f64 {
        let r = self.raw(d);
        if self.signed && self.size < 64 && (r >> (self.size - 1)) & 1 == 1 {
            (r | (u64::MAX << self.size)) as i64 as f64
        } else if self.signed {
            r as i64 as f64
        } else {
            r as f64
        }
    }

    /// The raw values the signal holds, lowest and highest (two's complement when signed).
    pub fn raw_range(&self) -> (i128, i128) {
        let n = self.size;
        if self.signed {
            (-(1i128 << (n - 1)), (1i128 << (n - 1)) - 1)
        } else {
            (0, (1i128 << n) - 1)
        }
    }

    /// The byte window: first byte, bytes, shift.
    pub(super) fn window(&self) -> (usize, usize, u32) {
        (self.first as usize, self.bytes as usize, u32::from(self.shift))
    }
}

/// The window's bytes as one big-endian (Motorola) or little-endian (Intel) number.
#[inline]
pub(super) fn gather<T>(w: &[u8], motorola: bool) -> T
where
    T: Default + From<u8> + std::ops::Shl<u32, Output = T> + std::ops::BitOr<Output = T>,
{
    let step = |v: T, b: &u8| (v << 8) | T::from(*b);
    if motorola {
        w.iter().fold(T::default(), step)
    } else {
        w.iter().rev().fold(T::default(), step)
    }
}

/// The mask of the low `size` bits (1..=64).
#[inline]
pub(super) fn low_bits(size: u8) -> u64 {
    u64::MAX >> (64 - u32::from(size))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The DBC's bit-by-bit definition, written out: the reference the windows are checked against.
    fn slow(start: u64, size: u64, motorola: bool, d: &[u8]) -> u64 {
        let bit = |p: u64| u64::from((d[(p >> 3) as usize] >> (p & 7)) & 1);
        let mut v = 0u64;
        let mut p = start;
        for k in 0..size {
            if motorola {
                v = (v << 1) | bit(p);
                p = if p.is_multiple_of(8) { p + 15 } else { p - 1 };
            } else {
                v |= bit(p) << k;
                p += 1;
            }
        }
        v
    }

    #[test]
    fn windows_read_what_the_bit_by_bit_definition_reads() {
        // a deterministic pseudo-random payload of 64 bytes
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut d = [0u8; 64];
        for b in d.iter_mut() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            *b = x as u8;
        }
        let mut n = 0;
        for len in [1usize, 2, 8, 12, 32, 64] {
            for start in 0..8 * len as u64 {
                for size in 1..=64u64 {
                    for motorola in [false, true] {
                        if let Ok(e) = Extractor::new(start, size, motorola, false, len) {
                            assert_eq!(
                                e.raw(&d[..len]),
                                slow(start, size, motorola, &d),
                                "len {len} start {start} size {size} m {motorola}"
                            );
                            n += 1;
                        }
                    }
                }
            }
        }
        assert!(n > 100_000, "{n}");
    }

    #[test]
    fn signed_values_and_refusals() {
        let e = Extractor::new(0, 16, false, true, 8).unwrap();
        assert_eq!(e.value(&(-1234i16).to_le_bytes()), -1234);
        let e = Extractor::new(7, 16, true, true, 8).unwrap();
        assert_eq!(e.value(&(-2i16).to_be_bytes()), -2);
        let e = Extractor::new(0, 64, false, true, 8).unwrap();
        assert_eq!(e.value(&i64::MIN.to_le_bytes()), i64::MIN as i128);
        assert!(Extractor::new(56, 16, false, false, 8).unwrap_err().contains("past the end"));
        assert!(Extractor::new(64, 1, false, false, 8).unwrap_err().contains("outside"));
        assert!(Extractor::new(0, 0, false, false, 8).is_err());
        // Motorola 16 bits starting at bit 7 of the last byte runs off the end
        assert!(Extractor::new(63, 16, true, false, 8).is_err());
    }
}
