//! candump `-l` log lines: `(1700000000.123456) vcan0 100#0A00F6FF14000100`.
//!
//! A zero-allocation parser and writer. `socketcan::dump::Reader` reads the
//! same format but allocates three times per line (line, device name, data);
//! replay must stream millions of lines a second, so this module parses in
//! place, and a test checks it against `socketcan::dump` line for line. Lines
//! are capped in length: a log of garbage with no newline costs bounded memory.

use std::io::{self, Read, Write};

/// Longest line accepted (a CAN FD line with 64 bytes and a long name is ~170).
pub const MAX_LINE: usize = 512;

/// CAN_ERR_FLAG of `linux/can.h`: set in the ID of an error frame.
pub const CAN_ERR_FLAG: u32 = 0x2000_0000;

/// A parsed log line. `data` holds `len` bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LogFrame<'a> {
    pub t_us: u64,
    pub iface: &'a [u8],
    pub id: u32,
    pub extended: bool,
    pub remote: bool,
    pub fd: bool,
    /// An error frame (CAN_ERR_FLAG in the ID).
    pub error: bool,
    pub len: usize,
    pub data: [u8; 64],
}

impl LogFrame<'_> {
    pub fn payload(&self) -> &[u8] {
        &self.data[..self.len]
    }
}

/// What is wrong with a line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LineError {
    #[error("bad timestamp (want \"(seconds.micros)\")")]
    Timestamp,
    #[error("missing interface name")]
    Interface,
    #[error("bad CAN ID (want 3 or 8 hex digits before '#')")]
    Id,
    #[error("bad payload (want pairs of hex digits, at most 8 bytes classic / 64 FD)")]
    Data,
    #[error("line longer than {MAX_LINE} bytes")]
    TooLong,
    #[error("unexpected text after the frame")]
    Trailing,
}

#[inline]
fn hex(c: u8) -> Option<u8> {
    match c {
        b'0'..=b'9' => Some(c - b'0'),
        b'a'..=b'f' => Some(c - b'a' + 10),
        b'A'..=b'F' => Some(c - b'A' + 10),
        _ => None,
    }
}

#[inline]
fn hex_bytes(s: &[u8], out: &mut [u8; 64], max: usize) -> Result<usize, LineError> {
    if !s.len().is_multiple_of(2) || s.len() / 2 > max {
        return Err(LineError::Data);
    }
    for (i, pair) in s.chunks_exact(2).enumerate() {
        let hi = hex(pair[0]).ok_or(LineError::Data)?;
        let lo = hex(pair[1]).ok_or(LineError::Data)?;
        out[i] = hi << 4 | lo;
    }
    Ok(s.len() / 2)
}

/// Parse one line (without its newline; a trailing '\r' is allowed).
pub fn parse_line(line: &[u8]) -> Result<LogFrame<'_>, LineError> {
    let line = match line.last() {
        Some(b'\r') => &line[..line.len() - 1],
        _ => line,
    };
    if line.len() > MAX_LINE {
        return Err(LineError::TooLong);
    }
    // (seconds.micros)
    if line.first() != Some(&b'(') {
        return Err(LineError::Timestamp);
    }
    let close = memchr::memchr(b')', line).ok_or(LineError::Timestamp)?;
    let ts = &line[1..close];
    let dot = ts.iter().position(|&c| c == b'.').ok_or(LineError::Timestamp)?;
    let (secs, micros) = (&ts[..dot], &ts[dot + 1..]);
    if secs.is_empty() || secs.len() > 12 || micros.len() != 6 {
        return Err(LineError::Timestamp);
    }
    let mut s: u64 = 0;
    for &c in secs {
        if !c.is_ascii_digit() {
            return Err(LineError::Timestamp);
        }
        s = s * 10 + (c - b'0') as u64;
    }
    let mut us: u64 = 0;
    for &c in micros {
        if !c.is_ascii_digit() {
            return Err(LineError::Timestamp);
        }
        us = us * 10 + (c - b'0') as u64;
    }
    let t_us = s * 1_000_000 + us;
    // " iface "
    let rest = &line[close + 1..];
    if rest.first() != Some(&b' ') {
        return Err(LineError::Interface);
    }
    let rest = &rest[1..];
    let sp = memchr::memchr(b' ', rest).ok_or(LineError::Interface)?;
    let iface = &rest[..sp];
    if iface.is_empty() {
        return Err(LineError::Interface);
    }
    let mut frame = &rest[sp + 1..];
    // An optional direction field (candump -x) after one more space.
    if let Some(sp2) = memchr::memchr(b' ', frame) {
        match &frame[sp2 + 1..] {
            b"R" | b"T" => frame = &frame[..sp2],
            _ => return Err(LineError::Trailing),
        }
    }
    let hash = memchr::memchr(b'#', frame).ok_or(LineError::Id)?;
    let id_s = &frame[..hash];
    let extended = match id_s.len() {
        3 => false,
        8 => true,
        _ => return Err(LineError::Id),
    };
    let mut id: u32 = 0;
    for &c in id_s {
        id = id << 4 | hex(c).ok_or(LineError::Id)? as u32;
    }
    let mut out = LogFrame { t_us, iface, id, extended, remote: false, fd: false, error: false, len: 0, data: [0; 64] };
    let body = &frame[hash + 1..];
    if extended && id & CAN_ERR_FLAG != 0 {
        out.error = true;
        out.id = id & 0x1FFF_FFFF;
        out.len = hex_bytes(body, &mut out.data, 8)?;
        return Ok(out);
    }
    if (!extended && id > 0x7FF) || (extended && id > 0x1FFF_FFFF) {
        return Err(LineError::Id);
    }
    match body.first() {
        Some(b'#') => {
            // CAN FD: "##<flags nibble><data>"
            if body.len() < 2 || hex(body[1]).is_none() {
                return Err(LineError::Data);
            }
            out.fd = true;
            out.len = hex_bytes(&body[2..], &mut out.data, 64)?;
        }
        Some(b'R') => {
            out.remote = true;
            match &body[1..] {
                [] => {}
                [d] if hex(*d).is_some_and(|v| v <= 8) => out.len = hex(*d).unwrap_or(0) as usize,
                _ => return Err(LineError::Data),
            }
        }
        _ => out.len = hex_bytes(body, &mut out.data, 8)?,
    }
    Ok(out)
}

/// Splits a byte stream into lines with bounded memory: a line longer than
/// `MAX_LINE` is skipped to its newline and reported as `Err(TooLong)`.
pub struct LineReader<R> {
    inner: R,
    buf: Vec<u8>,
    start: usize,
    end: usize,
    eof: bool,
    /// 1-based number of the line last returned.
    pub line_no: u64,
}

const BUF: usize = 1 << 20;

impl<R: Read> LineReader<R> {
    pub fn new(inner: R) -> Self {
        LineReader { inner, buf: vec![0; BUF], start: 0, end: 0, eof: false, line_no: 0 }
    }

    fn fill(&mut self) -> io::Result<()> {
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        while self.end < self.buf.len() && !self.eof {
            match self.inner.read(&mut self.buf[self.end..]) {
                Ok(0) => self.eof = true,
                Ok(n) => {
                    self.end += n;
                    // enough to make progress
                    if self.end - self.start > MAX_LINE {
                        break;
                    }
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }

    /// The next line without its newline; `None` at the end.
    pub fn next_line(&mut self) -> io::Result<Option<Result<&[u8], LineError>>> {
        loop {
            let window = &self.buf[self.start..self.end];
            if let Some(nl) = memchr::memchr(b'\n', window) {
                let s = self.start;
                self.start += nl + 1;
                self.line_no += 1;
                if nl > MAX_LINE + 1 {
                    return Ok(Some(Err(LineError::TooLong)));
                }
                return Ok(Some(Ok(&self.buf[s..s + nl])));
            }
            if window.len() > MAX_LINE + 1 {
                // Over-long line: discard up to its newline.
                self.line_no += 1;
                loop {
                    self.start = self.end;
                    self.fill()?;
                    let w = &self.buf[self.start..self.end];
                    if let Some(nl) = memchr::memchr(b'\n', w) {
                        self.start += nl + 1;
                        break;
                    }
                    if self.eof && self.start == self.end {
                        break;
                    }
                }
                return Ok(Some(Err(LineError::TooLong)));
            }
            if self.eof {
                if window.is_empty() {
                    return Ok(None);
                }
                let s = self.start;
                let e = self.end;
                self.start = self.end;
                self.line_no += 1;
                return Ok(Some(Ok(&self.buf[s..e])));
            }
            self.fill()?;
        }
    }
}

const HEX: &[u8; 16] = b"0123456789ABCDEF";

/// Append one candump -l line for a classic standard-ID frame.
#[inline]
pub fn write_line(out: &mut Vec<u8>, t_us: u64, iface: &[u8], id: u32, data: &[u8]) {
    // Assemble on the stack, then one copy: "(" secs "." micros ") " iface " " ID "#" hex "\n"
    let mut b = [0u8; 64];
    let mut n = 0;
    b[n] = b'(';
    n += 1;
    let secs = t_us / 1_000_000;
    let mut digits = [0u8; 20];
    let mut d = 0;
    let mut v = secs;
    loop {
        digits[d] = b'0' + (v % 10) as u8;
        d += 1;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    for k in (0..d).rev() {
        b[n] = digits[k];
        n += 1;
    }
    b[n] = b'.';
    n += 1;
    let mut v = (t_us % 1_000_000) as u32;
    for k in (0..6).rev() {
        b[n + k] = b'0' + (v % 10) as u8;
        v /= 10;
    }
    n += 6;
    b[n] = b')';
    b[n + 1] = b' ';
    n += 2;
    out.reserve(n + iface.len() + 6 + 2 * data.len());
    out.extend_from_slice(&b[..n]);
    out.extend_from_slice(iface);
    let mut t = [0u8; 22];
    t[0] = b' ';
    t[1] = HEX[(id >> 8 & 0xF) as usize];
    t[2] = HEX[(id >> 4 & 0xF) as usize];
    t[3] = HEX[(id & 0xF) as usize];
    t[4] = b'#';
    let mut m = 5;
    for &x in data.iter().take(8) {
        t[m] = HEX[(x >> 4) as usize];
        t[m + 1] = HEX[(x & 0xF) as usize];
        m += 2;
    }
    t[m] = b'\n';
    out.extend_from_slice(&t[..m + 1]);
}

/// A buffered candump writer.
pub struct LogWriter<W: Write> {
    out: W,
    buf: Vec<u8>,
    iface: Vec<u8>,
}

impl<W: Write> LogWriter<W> {
    pub fn new(out: W, iface: &str) -> Self {
        LogWriter { out, buf: Vec::with_capacity(BUF + 4096), iface: iface.as_bytes().to_vec() }
    }

    #[inline]
    pub fn frame(&mut self, t_us: u64, id: u32, data: &[u8]) -> io::Result<()> {
        write_line(&mut self.buf, t_us, &self.iface, id, data);
        if self.buf.len() >= BUF {
            self.flush_buf()?;
        }
        Ok(())
    }

    fn flush_buf(&mut self) -> io::Result<()> {
        self.out.write_all(&self.buf)?;
        self.buf.clear();
        Ok(())
    }

    pub fn finish(mut self) -> io::Result<W> {
        self.flush_buf()?;
        self.out.flush()?;
        Ok(self.out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_contract_example() {
        let f = parse_line(b"(1700000000.123456) vcan0 100#0A00F6FF14000100").unwrap();
        assert_eq!(f.t_us, 1_700_000_000_123_456);
        assert_eq!(f.iface, b"vcan0");
        assert_eq!(f.id, 0x100);
        assert_eq!(f.payload(), &[0x0A, 0x00, 0xF6, 0xFF, 0x14, 0x00, 0x01, 0x00]);
        let mut out = Vec::new();
        write_line(&mut out, f.t_us, f.iface, f.id, f.payload());
        assert_eq!(out, b"(1700000000.123456) vcan0 100#0A00F6FF14000100\n");
    }

    #[test]
    fn rejects_bad_lines() {
        for (l, e) in [
            (&b"(1700000000.12345) vcan0 100#00"[..], LineError::Timestamp),
            (b"1700000000.123456 vcan0 100#00", LineError::Timestamp),
            (b"(1700000000.123456)vcan0 100#00", LineError::Interface),
            (b"(1700000000.123456) vcan0 10#00", LineError::Id),
            (b"(1700000000.123456) vcan0 800#00", LineError::Id),
            (b"(1700000000.123456) vcan0 100#0G", LineError::Data),
            (b"(1700000000.123456) vcan0 100#000", LineError::Data),
            (b"(1700000000.123456) vcan0 100#000102030405060708", LineError::Data),
            (b"(1700000000.123456) vcan0 100#00 junk", LineError::Trailing),
            (b"", LineError::Timestamp),
        ] {
            assert_eq!(parse_line(l), Err(e), "{}", String::from_utf8_lossy(l));
        }
    }

    #[test]
    fn other_frame_kinds() {
        let f = parse_line(b"(1.000001) can0 12345678#AABB").unwrap();
        assert!(f.extended && f.id == 0x12345678 && f.len == 2);
        let f = parse_line(b"(1.000001) can0 100#R").unwrap();
        assert!(f.remote);
        let f = parse_line(b"(1.000001) can0 100##1AABBCC").unwrap();
        assert!(f.fd && f.len == 3);
        let f = parse_line(b"(1.000001) can0 20000004#0004000000000000").unwrap();
        assert!(f.error && f.id == 4);
        let f = parse_line(b"(1.000001) can0 100#11 R").unwrap();
        assert_eq!(f.len, 1);
    }

    #[test]
    fn line_reader_bounds_long_lines() {
        let mut data = Vec::new();
        data.extend_from_slice(b"(1.000001) can0 100#11\n");
        data.extend(std::iter::repeat_n(b'x', 3 * BUF));
        data.extend_from_slice(b"\n(1.000002) can0 100#22\nlast-no-newline");
        let mut r = LineReader::new(&data[..]);
        assert_eq!(r.next_line().unwrap().unwrap().unwrap(), b"(1.000001) can0 100#11");
        assert_eq!(r.next_line().unwrap().unwrap(), Err(LineError::TooLong));
        assert_eq!(r.next_line().unwrap().unwrap().unwrap(), b"(1.000002) can0 100#22");
        assert_eq!(r.line_no, 3);
        assert_eq!(r.next_line().unwrap().unwrap().unwrap(), b"last-no-newline");
        assert!(r.next_line().unwrap().is_none());
    }
}
