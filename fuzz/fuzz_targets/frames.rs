//! Frames decoded from fuzz bytes: mostly input IDs with 8-byte payloads
//! (so that samples do complete), sometimes anything else. Each frame takes
//! a control byte and up to 8 payload bytes. With `fix_checksums` an 8-byte
//! AUX frame (0x103) gets the checksum of the latest GYRO, ACCEL, MAGN
//! payloads, so that most samples reach the estimator.
use gyrocomp::adis::checksum;

pub struct Frame {
    pub t_us: u64,
    pub id: u32,
    pub extended: bool,
    pub remote: bool,
    pub fd: bool,
    pub len: usize,
    pub data: [u8; 64],
}

pub struct Frames<'a> {
    data: &'a [u8],
    t_us: u64,
    fix_checksums: bool,
    last: [[u8; 8]; 4],
}

impl<'a> Frames<'a> {
    pub fn new(data: &'a [u8], fix_checksums: bool) -> Self {
        Frames { data, t_us: 1_000_000, fix_checksums, last: [[0; 8]; 4] }
    }
}

impl Iterator for Frames<'_> {
    type Item = Frame;
    fn next(&mut self) -> Option<Frame> {
        let (&c, rest) = self.data.split_first()?;
        let len = if c & 0x80 != 0 { (c as usize >> 4) & 0x7 } else { 8 };
        let n = len.min(rest.len());
        let mut data = [0u8; 64];
        data[..n].copy_from_slice(&rest[..n]);
        self.data = &rest[n..];
        self.t_us += 1 + (c as u64 & 0x3) * 1000;
        let id = match c & 0x0C {
            0x0C if c & 0x40 != 0 => 0x7FF & (u32::from(data[0]) << 3 | u32::from(c)),
            _ => 0x100 + u32::from(c & 0x3),
        };
        let f = Frame { t_us: self.t_us, id, extended: c & 0xF0 == 0xF0, remote: c & 0xF0 == 0xE0, fd: c & 0xF0 == 0xD0, len, data };
        if (0x100..=0x103).contains(&id) && len == 8 && !(f.extended || f.remote || f.fd) {
            let part = (id - 0x100) as usize;
            self.last[part].copy_from_slice(&data[..8]);
            if part == 3 && self.fix_checksums {
                let cs = checksum(&self.last);
                let mut f = f;
                f.data[6..8].copy_from_slice(&cs.to_le_bytes());
                return Some(f);
            }
        }
        Some(f)
    }
}
